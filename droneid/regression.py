"""Robust, physics-bounded linear least squares, its blocked cross-validation and its intervals.

Every least-squares refit of droneid (the prior's scales, effect parameters, evolved terms kept
by the ladder) goes through :func:`robust_fit`:

- **Loss: Huber**, by iteratively reweighted least squares (IRLS). A residual within
  ``HUBER_C = 1.345`` robust scales (``1.4826 · MAD`` of the residuals) has weight 1, a larger one
  weight ``HUBER_C·s/|r|``: quadratic near zero, linear in the tails, 95 % as efficient as least
  squares on Gaussian noise, and a few bad rows cannot move a coefficient far.
- **Bounds.** Each coefficient has a physical range ``[lo, hi]`` (a thrust scale > 0, a drag
  coefficient >= 0), declared by the prior (:data:`priors.base.ROLE_BOUNDS`). A coefficient with
  ``lo == hi`` is fixed (known physics, e.g. gravity: not a free parameter). Bounded steps use
  :func:`scipy.optimize.lsq_linear`.

:func:`blocked_cv` gives held-out predictions (each block predicted by the fit on the others);
:func:`block_bootstrap` gives 95 % intervals by resampling whole time blocks of the training
flights with replacement (the blocks keep the autocorrelation of the residuals inside them).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

__all__ = ["RobustFit", "robust_fit", "weighted_bounded_lstsq", "blocked_cv", "block_bootstrap",
           "HUBER_C", "LOSS", "N_BOOT"]

#: Huber's tuning constant, in robust scales of the residuals (95 % Gaussian efficiency)
HUBER_C = 1.345
#: what the reports say the loss is
LOSS = "Huber (c = 1.345 robust scales, IRLS), bounded by physics"
#: bootstrap replicates of :func:`block_bootstrap`
N_BOOT = 200


@dataclass(frozen=True)
class RobustFit:
    """beta : coefficients; weights : the final IRLS weights of the rows (1 = full weight);
    scale : the robust residual scale (target units); at_bound : per coefficient, True where
    the bound is active (the data pull it outside its physical range)"""
    beta: np.ndarray
    weights: np.ndarray
    scale: float
    at_bound: np.ndarray


def _bounds(k: int, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    lo = np.full(k, -np.inf) if lo is None else np.asarray(lo, float).copy()
    hi = np.full(k, np.inf) if hi is None else np.asarray(hi, float).copy()
    return lo, hi


def weighted_bounded_lstsq(A: np.ndarray, y: np.ndarray, w: np.ndarray | None = None,
                           lo=None, hi=None) -> np.ndarray:
    """argmin Σ w·(y − Aβ)² subject to lo <= β <= hi (lo == hi fixes a coefficient). Columns
    are normalised first; collinear columns get a minimum-norm share; zero columns get 0 (or their
    fixed value)."""
    A = np.asarray(A, float)
    y = np.asarray(y, float)
    k = A.shape[1]
    lo, hi = _bounds(k, lo, hi)
    beta = np.zeros(k)
    if k == 0:
        return beta
    fixed = lo == hi
    beta[fixed] = lo[fixed]
    free = ~fixed
    r = y - A[:, fixed] @ lo[fixed] if fixed.any() else y
    if not free.any():
        return beta
    ww = np.ones(y.size) if w is None else np.asarray(w, float)
    Af = A[:, free]
    # normal equations on normalised columns (k x k: fast for thousands of rows); an
    # eigendecomposition gives the minimum-norm share to collinear columns
    norms = np.sqrt(np.einsum("ij,ij,i->j", Af, Af, ww))
    zero = norms == 0
    norms[zero] = 1.0
    An = Af / norms
    G = An.T @ (An * ww[:, None])
    g = An.T @ (ww * r)
    e, V = np.linalg.eigh(G)
    keep = e > 1e-12 * max(float(e[-1]), 1e-300)
    c = V.T @ g
    b = V[:, keep] @ (c[keep] / e[keep])
    b[zero] = 0.0
    flo, fhi = lo[free] * norms, hi[free] * norms
    if np.any(b < flo - 1e-12 * np.abs(flo)) or np.any(b > fhi + 1e-12 * np.abs(fhi)):
        # the same problem on M = diag(√e) Vᵀ (MᵀM = G): ||M b − diag(1/√e) Vᵀ g||² + const
        se = np.sqrt(e[keep])
        M = se[:, None] * V[:, keep].T
        b = lsq_linear(M, c[keep] / se, bounds=(flo, fhi), method="bvls" if An.shape[1] <= 20 else "trf").x
    beta[free] = np.clip(b / norms, lo[free], hi[free])   # a zero column: 0, or its nearest bound
    return beta


def _scale(r: np.ndarray) -> float:
    med = np.median(r)
    s = 1.4826 * float(np.median(np.abs(r - med)))
    return s if s > 0 else float(np.sqrt(np.mean(r * r))) or 1e-12


def robust_fit(A: np.ndarray, y: np.ndarray, lo=None, hi=None, *, max_iter: int = 30,
               tol: float = 1e-6, w0: np.ndarray | None = None) -> RobustFit:
    """Huber-loss IRLS fit of ``y ≈ A β`` with ``lo <= β <= hi`` (see the module docstring);
    ``w0``: starting weights (e.g. a fit on more rows), 1 by default."""
    A = np.asarray(A, float)
    y = np.asarray(y, float)
    k = A.shape[1]
    lo, hi = _bounds(k, lo, hi)
    bad = ~(np.isfinite(y) & np.all(np.isfinite(A), axis=1))
    if bad.any():             # a row that cannot be evaluated weighs nothing
        A, y = np.where(bad[:, None], 0.0, A), np.where(bad, 0.0, y)
    w = np.ones(y.size) if w0 is None else np.asarray(w0, float).copy()
    w[bad] = 0.0
    if not (w > 0).any():     # no usable row: every coefficient at its nearest bound to 0
        zero = np.clip(np.zeros(k), lo, hi)
        return RobustFit(zero, w, float("nan"), np.zeros(k, bool))
    beta = weighted_bounded_lstsq(A, y, w, lo, hi)
    s = 1e-12
    for _ in range(max_iter):
        r = y - A @ beta
        s = _scale(r[~bad])
        u = np.abs(r) / (HUBER_C * s)
        w = np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-300))
        w[bad] = 0.0
        new = weighted_bounded_lstsq(A, y, w, lo, hi)
        moved = float(np.max(np.abs(A @ (new - beta)))) if k else 0.0   # in target units
        beta = new
        if moved <= tol * s:
            break
    span = np.maximum(np.abs(lo), np.abs(hi))
    eps = 1e-9 * np.where(np.isfinite(span), np.maximum(span, 1.0), 1.0)
    at_bound = (~(lo == hi)) & ((np.abs(beta - lo) <= eps) | (np.abs(beta - hi) <= eps))
    return RobustFit(beta, w, s, at_bound)


def blocked_cv(A: np.ndarray, y: np.ndarray, blocks: np.ndarray, lo=None, hi=None) -> np.ndarray:
    """Held-out predictions on ``A`` (an intercept column included by the caller, if any): every
    block is predicted by the bounded least squares on all other blocks, with the robust (Huber)
    weights of :func:`robust_fit` on all rows (one step per fold instead of a full IRLS: the
    weights are a property of the training rows, and this keeps a CV at one solve per block)."""
    A = np.asarray(A, float)
    pred = np.empty_like(np.asarray(y, float))
    w = robust_fit(A, y, lo, hi).weights
    for b in np.unique(blocks):
        hold = blocks == b
        beta = weighted_bounded_lstsq(A[~hold], y[~hold], w[~hold], lo, hi)
        pred[hold] = A[hold] @ beta
    return pred


def block_bootstrap(A: np.ndarray, y: np.ndarray, blocks: np.ndarray, fit: RobustFit, lo=None, hi=None,
                    *, n_boot: int = N_BOOT, seed: int = 0, level: float = 0.95) -> np.ndarray:
    """(k, 2) percentile interval of each coefficient: whole blocks resampled with replacement,
    each replicate refit with the full fit's robust weights (one bounded least squares each)."""
    A = np.asarray(A, float)
    ids = np.unique(blocks)
    rows = [np.flatnonzero(blocks == b) for b in ids]
    rng = np.random.default_rng(seed)
    draws = np.empty((n_boot, A.shape[1]))
    for i in range(n_boot):
        pick = np.concatenate([rows[j] for j in rng.integers(0, ids.size, ids.size)])
        draws[i] = weighted_bounded_lstsq(A[pick], y[pick], fit.weights[pick], lo, hi)
    a = 100 * (1 - level) / 2
    return np.percentile(draws, [a, 100 - a], axis=0).T
