"""One calibrated rule for every "add it or not" decision on training data.

A candidate (an effect, an effect pair, an input delay, an evolved term) is kept only when the
model WITH it predicts held-out training data better than the model WITHOUT it, consistently
over contiguous time blocks, at a family-wise error level over every candidate tried.

The rule (:func:`decide`), on per-row held-out (cross-validated) residuals of the two models:

1. **Block differences.** For every validation block b (contiguous time blocks of the training
   flights, ``block_ids``):
   ``d_b = ln(mse0_b / mse1_b)`` with ``mse*_b`` the mean squared held-out residual in block b
   without/with the candidate (row weights optional): the log ratio of the block's validation
   errors, so a calm block and a manoeuvre count alike (raw differences let the noisiest blocks
   dominate the spread and cost most of the power), and a block twice as bad weighs as much as a
   block twice as good. (The relative drop ``(mse0_b − mse1_b)/mse0_b`` used before is bounded
   by 1 above but not below: one block where the candidate's constant meets a local residual
   near zero, e.g. a gust against the mean wind, outweighed many blocks that improved, and under
   "no effect" it is skewed, which the sign-flip test assumes it is not.) ``d_b > 0``: the
   candidate helps there.
2. **Paired one-sided sign-flip test.** Under "the candidate does not help", each ``d_b`` is as
   likely to be negative as positive; ``p`` is the share of the 2^B sign patterns whose mean
   is at least the observed ``mean(d)`` (exact for B ≤ 14, else ``N_FLIPS`` fixed-seed random
   patterns, ``p = (1 + hits)/(1 + N_FLIPS)``). Blocks, not rows, are the units: residuals are
   correlated in time, blocks of a few seconds are nearly independent, so the test does not count
   one manoeuvre hundreds of times. No normality is assumed, so a gain concentrated in a few
   blocks (ground effect near the ground only) is not penalised as a Student t would be; the
   price is a floor: p ≥ 2^−B, so B must be ≥ log2(m/α) blocks (12 blocks for m = 13 at α = 0.01;
   the evidence says so when they are too few). The t statistic is reported alongside.
3. **Family-wise error control (Holm).** With ``family_size`` = m candidates tried in all and
   the candidate at position ``rank`` k of the step-down order (k = 1 for the first one
   accepted), the threshold is ``alpha / (m − k + 1)`` (k = 1: Bonferroni).
   :func:`decide_family` applies the whole Holm step-down to several candidates at once.
4. **Size.** The pooled held-out RMSE must fall by at least ``min_effect_pct`` percent: a
   consistent but negligible gain (a long flight makes anything significant) is not kept.

Accepted when p < threshold AND the size holds. Everything is a function of plain arrays (the
residuals or predictions of the two models and the block ids), so the diagnosis, the delay
choice and the trimming of evolved terms share it. Test flights must never be passed here.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from droneid.errors import ConfigError
from droneid.core.regression import blocked_cv

__all__ = ["Decision", "decide", "decide_units", "p_text", "decide_predictions", "decide_designs", "decide_family",
           "holm_step_down",
           "block_differences", "block_log_ratios", "paired_block_test", "holm_threshold", "N_FLIPS"]

#: random sign patterns of the sign-flip test when 2^B is too many to enumerate (B > 16)
N_FLIPS = 50_000
_EXACT_MAX_BLOCKS = 14


@dataclass(frozen=True)
class Decision:
    """The outcome of :func:`decide` for one candidate.

    accepted: the candidate is kept. statistic: the paired t statistic of the block differences.
    p_value: its one-sided p. threshold: the p it had to beat (Holm). n_blocks: validation blocks
    used. effect_pct: held-out RMSE reduction in % (positive: the candidate helps). evidence:
    one line for a report. rmse_without/rmse_with: pooled held-out RMSE of the two models (the
    residuals' units). blocks_better: blocks where the candidate helps. block_differences:
    ``d_b = ln(mse0_b / mse1_b)``, the log ratio of each block's held-out MSE without/with
    the candidate. family_size, rank: the Holm
    position. reasons: why it was rejected (empty when accepted).
    """
    accepted: bool
    statistic: float
    p_value: float
    threshold: float
    n_blocks: int
    effect_pct: float
    evidence: str
    rmse_without: float = float("nan")
    rmse_with: float = float("nan")
    blocks_better: int = 0
    block_differences: tuple[float, ...] = ()
    family_size: int = 1
    rank: int = 1
    reasons: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        d = asdict(self)
        d["block_differences"] = list(self.block_differences)
        d["reasons"] = list(self.reasons)
        return d


def holm_threshold(alpha: float, family_size: int, rank: int = 1) -> float:
    """The p a candidate at Holm position ``rank`` (1-based) of ``family_size`` must beat:
    ``alpha / (family_size − rank + 1)``."""
    if not (0 < alpha < 1):
        raise ConfigError(f"The 'alpha' parameter must be in (0, 1). Got {alpha!r} instead.")
    if not (isinstance(family_size, (int, np.integer)) and family_size >= 1):
        raise ConfigError(f"The 'family_size' parameter must be an int >= 1. Got {family_size!r} instead.")
    if not (isinstance(rank, (int, np.integer)) and 1 <= rank <= family_size):
        raise ConfigError(f"The 'rank' parameter must be an int in [1, family_size={family_size}]. "
                          f"Got {rank!r} instead.")
    return alpha / (family_size - rank + 1)


def block_differences(err_without, err_with, blocks, weights=None):
    """Per-block mean squared errors of the two models and their difference.

    ``err_*``: per-row held-out residuals (any units, the same rows); ``blocks``: block id per
    row; ``weights``: optional per-row weights (≥ 0) of the squared errors. Returns
    ``(block ids, mse_without_b, mse_with_b, d_b, rows_b)``, ``d_b = mse_without_b − mse_with_b``.
    Rows with a non-finite residual in either model are dropped.
    """
    e0 = np.asarray(err_without, float).ravel()
    e1 = np.asarray(err_with, float).ravel()
    b = np.asarray(blocks).ravel()
    if not (e0.size == e1.size == b.size):
        raise ConfigError(f"err_without, err_with and blocks must have the same length. Got "
                          f"{e0.size}, {e1.size} and {b.size} instead.")
    w = np.ones(e0.size) if weights is None else np.asarray(weights, float).ravel()
    if w.size != e0.size or np.any(w < 0):
        raise ConfigError("weights must be one non-negative number per row")
    ok = np.isfinite(e0) & np.isfinite(e1) & np.isfinite(w)
    e0, e1, b, w = e0[ok], e1[ok], b[ok], w[ok]
    ids, inv = np.unique(b, return_inverse=True)
    sw = np.bincount(inv, weights=w, minlength=ids.size)
    rows = np.bincount(inv, minlength=ids.size)
    keep = sw > 0
    m0 = np.bincount(inv, weights=w * e0 * e0, minlength=ids.size)[keep] / sw[keep]
    m1 = np.bincount(inv, weights=w * e1 * e1, minlength=ids.size)[keep] / sw[keep]
    return ids[keep], m0, m1, m0 - m1, rows[keep]


def block_log_ratios(mse_without, mse_with) -> np.ndarray:
    """``ln(mse_without_b / mse_with_b)`` per block (> 0: the candidate helps there); 0 for a block
    where either error is 0 (nothing to compare)."""
    m0 = np.asarray(mse_without, float)
    m1 = np.asarray(mse_with, float)
    ok = (m0 > 0) & (m1 > 0)
    return np.where(ok, np.log(np.where(ok, m0, 1.0) / np.where(ok, m1, 1.0)), 0.0)


def paired_block_test(d) -> tuple[float, float]:
    """(t, one-sided p) for "the block differences ``d`` have a positive centre": ``t`` the
    paired t statistic (reported), ``p`` from the sign-flip distribution of mean(d) (exact for
    up to 14 blocks, else :data:`N_FLIPS` fixed-seed random sign patterns)."""
    d = np.asarray(d, float)
    b = d.size
    if b == 0:
        return 0.0, 1.0
    mean = float(np.mean(d))
    sd = float(np.std(d, ddof=1)) if b >= 2 else 0.0
    if sd > 1e-15 * max(1.0, abs(mean)):
        t = mean / (sd / math.sqrt(b))
    else:
        t = math.inf if mean > 0 else (-math.inf if mean < 0 else 0.0)
    obs = float(np.sum(d)) * (1 - 1e-12)      # ties (equal |d|) count as "at least as large"
    if b <= _EXACT_MAX_BLOCKS:
        signs = 1 - 2 * ((np.arange(2 ** b)[:, None] >> np.arange(b)) & 1)
        hits = int(np.sum(signs @ d >= obs))
        return float(t), hits / 2 ** b
    hits = 0
    for signs in _sign_patterns(b):
        hits += int(np.sum(signs.astype(np.float64) @ d >= obs))
    return float(t), (1 + hits) / (1 + N_FLIPS)


@functools.lru_cache(maxsize=8)
def _sign_patterns(b: int) -> tuple[np.ndarray, ...]:
    """The :data:`N_FLIPS` fixed-seed random sign patterns of :func:`paired_block_test` for ``b``
    blocks, in chunks of 10 000 (int8, ±1): drawn once per process and block count (drawing them
    was nearly all of a test's time; they do not depend on the data, so every p is the same)."""
    rng = np.random.default_rng(20251125)
    chunks = tuple(rng.choice((-1.0, 1.0), size=(10_000, b)).astype(np.int8) for _ in range(N_FLIPS // 10_000))
    for c in chunks:
        c.setflags(write=False)     # shared by every later test of this process
    return chunks


def decide(err_without, err_with, blocks, *, alpha: float = 0.01, family_size: int = 1,
           rank: int = 1, min_effect_pct: float = 1.0, weights=None, what: str = "") -> Decision:
    """The rule of this module for one candidate (see the module docstring).

    ``err_without``/``err_with``: per-row held-out residuals of the model without/with the
    candidate on TRAINING data (e.g. ``y − blocked_cv(...)``); ``blocks``: their validation block
    ids (at least 3 blocks); ``alpha``: family-wise level; ``family_size``/``rank``: the Holm
    position (:func:`holm_threshold`); ``min_effect_pct``: smallest held-out RMSE reduction (%)
    that counts; ``weights``: optional per-row weights; ``what``: a name for the evidence line.
    """
    _, m0, m1, _, rows = block_differences(err_without, err_with, blocks, weights)
    return decide_units(m0, m1, rows, alpha=alpha, family_size=family_size, rank=rank,
                        min_effect_pct=min_effect_pct, what=what)


#: how :func:`decide_units` reads its per-unit errors: (what the pooled figure is called, the
#: units' name, whether the errors are squared (the effect is then on their root))
_LOSSES = {"mse": ("CV RMSE", "blocks", True), "simerr": ("SimErr", "cells", False)}


def p_text(p: float, threshold: float) -> tuple[str, str]:
    """(``p``, ``threshold``) as text with 2 significant digits, or as many more (up to 8) as it
    takes for the two to differ and to compare as the numbers do: a p of 0.0099998 against 0.01
    reads "0.0099998" and "0.01", not "0.01 < 0.01"; 0.00332 against 0.01/3 "0.00332" and
    "0.00333", not "0.00332 < 0.0033"."""
    p, threshold = float(p), float(threshold)
    for digits in range(2, 9):
        ps, ts = f"{p:.{digits}g}", f"{threshold:.{digits}g}"
        if p == threshold or not (math.isfinite(p) and math.isfinite(threshold)):
            return ps, ts
        if ps != ts and (float(ps) < float(ts)) == (p < threshold):
            return ps, ts
    return repr(p), repr(threshold)


def decide_units(loss_without, loss_with, rows=None, *, alpha: float = 0.01, family_size: int = 1,
                 rank: int = 1, min_effect_pct: float = 1.0, loss: str = "mse", what: str = "") -> Decision:
    """The rule (module docstring, steps 2-4) on one held-out error per unit of each model.

    ``loss_without``/``loss_with`` (U,): each unit's held-out error without/with the candidate,
    ≥ 0, in the same units; ``rows`` (U,): the rows (or windows) behind each unit, the weights of
    the pooled error (default 1 each). ``loss``: ``"mse"``, the units' mean squared residuals
    (:func:`decide` passes its blocks'; the effect is the drop of the pooled RMSE, the root of
    the row-weighted mean), or ``"simerr"``, a mean open-loop simulation error per unit (e.g. a
    (flight, regime) cell's mean SimErr of held-out windows, rad/s; the effect is the drop of the
    row-weighted mean itself, the units are called cells). The test is on ``d_u = ln(loss_without_u /
    loss_with_u)`` (:func:`block_log_ratios`, :func:`paired_block_test`); ``alpha``,
    ``family_size``, ``rank``, ``min_effect_pct`` and ``what`` as :func:`decide`. At least 3 units.
    """
    if loss not in _LOSSES:
        raise ConfigError(f"The 'loss' parameter of decide_units must be one of {', '.join(_LOSSES)}. "
                          f"Got {loss!r} instead.")
    if not (0 <= min_effect_pct < 100):
        raise ConfigError(f"The 'min_effect_pct' parameter must be in [0, 100). Got {min_effect_pct!r} instead.")
    thr = holm_threshold(alpha, family_size, rank)
    m0 = np.asarray(loss_without, float).ravel()
    m1 = np.asarray(loss_with, float).ravel()
    rows = np.ones(m0.size) if rows is None else np.asarray(rows, float).ravel()
    if not (m0.size == m1.size == rows.size):
        raise ConfigError(f"loss_without, loss_with and rows must have the same length. Got "
                          f"{m0.size}, {m1.size} and {rows.size} instead.")
    label, units, squared = _LOSSES[loss]
    if m0.size < 3:
        raise ConfigError(f"decide needs at least 3 validation {units} with data. Got {m0.size} instead.")
    pooled0 = float(np.sum(m0 * rows) / np.sum(rows))
    pooled1 = float(np.sum(m1 * rows) / np.sum(rows))
    dn = block_log_ratios(m0, m1)
    t, p = paired_block_test(dn)
    p_s, thr_s = p_text(p, thr)
    r0, r1 = (math.sqrt(pooled0), math.sqrt(pooled1)) if squared else (pooled0, pooled1)
    pct = 100.0 * (1.0 - r1 / r0) if r0 > 0 else 0.0
    better = int(np.sum(m0 - m1 > 0))
    n = int(m0.size)
    reasons = []
    if not p < thr:
        reasons.append(f"{'block' if squared else 'cell'} test p = {p_s} ≥ {thr_s}")
        if 2.0 ** -n >= thr:
            reasons.append(f"{n} {units} cannot reach p < {thr:.2g} (a sign-flip p is ≥ 2^−B): "
                           f"use more {units}")
    if pct < min_effect_pct:
        reasons.append(f"held-out {'RMSE' if squared else label} {'falls' if pct >= 0 else 'rises'} by "
                       f"{abs(pct):.2f} % ({'<' if pct >= 0 else 'not'} {min_effect_pct:g} %)")
    accepted = not reasons
    holm = (f"Bonferroni over {family_size}" if rank == 1 else f"Holm rank {rank} of {family_size}")
    # the pooled error and the typical unit can move apart (a few units carry the pooled gain):
    # a fall of the pooled error beside p = 1 must not read as a gain the test ignored
    apart = (pct > 0 and t < 0) or (pct < 0 and t > 0)
    change = f"{-pct:+.1f} %" + (f", pooled over the rows; the typical {units[:-1] if units.endswith('s') else units} "
                                 f"{'gets worse' if t < 0 else 'improves'}" if apart else "")
    line = (f"{what + ': ' if what else ''}{label} {r0:.4g} -> {r1:.4g} ({change}), "
            f"t = {t:.2f} over {n} {units}, sign-flip p = {p_s} "
            f"{'<' if p < thr else '≥'} {thr_s} (α = {alpha:g}, {holm}), "
            f"{better}/{n} {units} better: " + ("accepted" if accepted else
                                                "rejected (" + "; ".join(reasons) + ")"))
    return Decision(accepted, float(t), float(p), float(thr), n, float(pct), line,
                    r0, r1, better, tuple(float(x) for x in dn), int(family_size), int(rank),
                    tuple(reasons))


def decide_predictions(y, pred_without, pred_with, blocks, **kwargs) -> Decision:
    """:func:`decide` from held-out predictions of the two models of ``y`` (same rows)."""
    y = np.asarray(y, float)
    return decide(y - np.asarray(pred_without, float), y - np.asarray(pred_with, float), blocks, **kwargs)


def decide_designs(A_without, A_with, y, blocks, **kwargs) -> Decision:
    """:func:`decide` for two least-squares models given by their design matrices (include an
    intercept column if the model has one): held-out predictions by
    :func:`droneid.core.regression.blocked_cv` over ``blocks``."""
    y = np.asarray(y, float)
    return decide_predictions(y, blocked_cv(np.asarray(A_without, float), y, blocks),
                              blocked_cv(np.asarray(A_with, float), y, blocks), blocks, **kwargs)


def decide_family(err_without, candidates: Mapping[str, np.ndarray], blocks, *, alpha: float = 0.01,
                  family_size: int | None = None, min_effect_pct: float = 1.0, weights=None
                  ) -> dict[str, Decision]:
    """Holm's step-down over several candidates, each against the same model without them.

    ``candidates``: {name: per-row held-out residuals with that candidate}; ``family_size``:
    default the number of candidates (larger when others were tried elsewhere). Candidates are
    ordered by p; the k-th is tested at ``alpha / (m − k + 1)``; after the first rejection every
    later one is rejected too (Holm, :func:`holm_step_down`). Returns {name: Decision} in the
    input order; choose among the accepted ones (e.g. the lowest held-out error).
    """
    names: Sequence[str] = list(candidates)
    m = len(names) if family_size is None else int(family_size)
    if m < len(names):
        raise ConfigError(f"family_size ({m}) is smaller than the number of candidates ({len(names)})")
    return holm_step_down(lambda n, k: decide(err_without, candidates[n], blocks, alpha=alpha,
                                              family_size=max(m, 1), rank=k, min_effect_pct=min_effect_pct,
                                              weights=weights, what=n), names)


def holm_step_down(decide_at: Callable[[str, int], Decision], names: Sequence[str]) -> dict[str, Decision]:
    """Holm's step-down over the candidates ``names``, each decided by ``decide_at(name, rank)``
    (a :class:`Decision` at Holm position ``rank``; the caller fixes alpha and the family size,
    which may exceed ``len(names)``). The candidates are ordered by their p at rank 1 (ties by
    name); the k-th is decided at rank k; after the first whose p misses its threshold every later
    one is rejected too (a candidate rejected for its size alone does not stop the order).
    Returns {name: Decision} in the order of ``names``."""
    names = list(names)
    first = {n: decide_at(n, 1) for n in names}
    order = sorted(names, key=lambda n: (first[n].p_value, n))
    out, stopped = {}, False
    for k, n in enumerate(order, 1):
        dec = decide_at(n, k)
        if stopped and dec.accepted:
            dec = Decision(**{**asdict(dec), "accepted": False,
                              "reasons": dec.reasons + ("an earlier candidate of the Holm order failed",),
                              "evidence": dec.evidence.replace(": accepted", ": rejected (an earlier "
                                                               "candidate of the Holm order failed)")})
        stopped = stopped or not dec.p_value < dec.threshold
        out[n] = dec
    return {n: out[n] for n in names}
