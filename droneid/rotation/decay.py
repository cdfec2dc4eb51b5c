"""The rate-decay rung of the rotational ladder (issue 28): ``ω̇_k = −c_k ω_k`` per body axis, its
decay ``c`` fitted by the worst regime of the open-loop body-rate error on TRAINING flights, and
its block-bootstrap interval. :func:`droneid.rotation.choice.select_rotation` climbs the ladder
with it; the regimes (:func:`regime_of`) are the ladder's too. Rates in rad/s, decays in 1/s.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from droneid.errors import ConfigError, DataError
from droneid.simulation.openloop import StateLog
from droneid.core.regression import N_BOOT
from droneid.rotation.model import segment_bounds
from droneid.dataset.validation import time_blocks

__all__ = ["DAMPING_GRID", "fit_damping", "damping_folds", "damping_interval", "regime_of"]

#: rate decays (1/s) tried by :func:`fit_damping` and by
#: :func:`droneid.rotation.choice.fit_rotation_multistep`
DAMPING_GRID = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)


def fit_damping(logs: Sequence[StateLog], *, grid: Sequence[float] = DAMPING_GRID, horizon: int = 50,
                stride: int = 5, regimes: int = 4) -> np.ndarray:
    """Per body axis the rate decay ``c`` (1/s) of ``ω̇_k = −c ω_k`` from ``grid`` with the lowest
    worst-regime open-loop error on the training flights. Each window (every ``stride``-th start
    in flight) has the error ``Σ_{h=1..horizon} |ω_{t+h} − e^{−c h dt} ω_t|``; the windows are
    split into ``regimes`` classes by their error with the rate held (``c = 0``; quantiles), and
    ``c`` minimises the largest ratio over classes of its mean error to the held one (the smallest
    ``c`` wins a tie), the criterion :func:`droneid.rotation.choice.select_rotation` judges the
    rungs by: a decay fitted to the pooled error follows the hard manoeuvres alone. Returns (3,)."""
    err, _, _ = _decay_errors(logs, grid, horizon, stride)
    return np.asarray(grid, float)[_best_decay(err, regimes)]


def damping_folds(logs: Sequence[StateLog], *, grid: Sequence[float] = DAMPING_GRID, horizon: int = 50,
                  stride: int = 5, regimes: int = 4) -> dict[str, np.ndarray]:
    """{flight name: :func:`fit_damping` on every other flight (logs of one name are one flight)}:
    the windows' errors are computed once and each fold chooses on the other flights' windows (the
    same windows in the same order as a fit on those flights alone: the same decays)."""
    err, _, flight = _decay_errors(logs, grid, horizon, stride)
    names = list(dict.fromkeys(log.name for log in logs))
    g = np.asarray(grid, float)
    out = {}
    for j, name in enumerate(names):
        if not np.any(flight != j):
            raise DataError(f"fit_damping: no flight segment longer than {int(horizon)} steps besides {name}")
        out[name] = g[_best_decay(err[:, flight != j], regimes)]
    return out


def damping_interval(logs: Sequence[StateLog], *, grid: Sequence[float] = DAMPING_GRID, horizon: int = 50,
                     stride: int = 5, regimes: int = 4, n_boot: int = N_BOOT, seed: int = 0,
                     level: float = 0.95) -> np.ndarray:
    """(3, 2): per body axis the spread (1/s) of :func:`fit_damping`'s choice over a block
    bootstrap, its ``level`` percentile interval: the windows of each flight are cut into
    contiguous time blocks (:func:`droneid.dataset.validation.time_blocks`, 8-20 a flight), every block
    of every flight is one unit, the units are resampled with replacement ``n_boot`` times and
    the decay is chosen again on each replicate by the same criterion. The decay lives on
    ``grid`` (steps of ×2), so the bounds are grid values, the lower one rounded down and the
    upper one up (never narrower than the percentiles); an upper bound at the grid's top means
    "that much or more". A choice on a grid has no exact coverage guarantee: see the docs."""
    if not 0.0 < level < 1.0:
        raise ConfigError(f"The 'level' parameter of damping_interval must be in (0, 1). Got {level!r} instead.")
    err, t, flight = _decay_errors(logs, grid, horizon, stride)
    units = time_blocks(t, flight)       # block b of flight f: its own unit
    rows = [np.flatnonzero(units == u) for u in np.unique(units)]
    rng = np.random.default_rng(seed)
    picks = np.empty((int(n_boot), 3), dtype=int)
    for i in range(int(n_boot)):
        pick = np.concatenate([rows[j] for j in rng.integers(0, len(rows), len(rows))])
        picks[i] = _best_decay(err[:, pick], regimes)
    a = 100 * (1 - level) / 2
    g = np.asarray(grid, float)
    lo = np.percentile(picks, a, axis=0, method="lower")
    hi = np.percentile(picks, 100 - a, axis=0, method="higher")
    return np.column_stack([g[lo.astype(int)], g[hi.astype(int)]])


def _decay_errors(logs: Sequence[StateLog], grid, horizon: int, stride: int):
    """(err (G + 1, W, 3), t (W,), flight (W,)): each window's open-loop body-rate error with the
    rate held (first) and with each decay of ``grid``, its start time (s) and its flight's index
    (logs of one name are one flight)."""
    H = int(horizon)
    names = list(dict.fromkeys(log.name for log in logs))
    rates = np.concatenate([[0.0], np.asarray(grid, float)])
    errs, ts, fl = [], [], []
    for log in logs:
        for a, b in segment_bounds(log, H + 1):
            w = log.state[a:b, 10:13]
            starts = np.arange(0, b - a - H, stride)
            if not starts.size:
                continue
            w0, wt = w[starts], w[starts[:, None] + np.arange(1, H + 1)[None, :]]     # (W, 3), (W, H, 3)
            decay = np.exp(-np.outer(rates, log.dt_s * np.arange(1, H + 1)))  # (G + 1, H)
            errs.append(np.abs(wt[None] - decay[:, None, :, None] * w0[None, :, None, :]).sum(axis=2))
            ts.append(log.t_s[a + starts])
            fl.append(np.full(starts.size, names.index(log.name)))
    if not errs:
        raise DataError(f"fit_damping: no flight segment longer than {H} steps")
    return np.concatenate(errs, axis=1), np.concatenate(ts), np.concatenate(fl)


def _best_decay(err: np.ndarray, regimes: int) -> np.ndarray:
    """(3,) index into the grid of the decay with the lowest worst-regime error ratio to the held
    rate (:func:`fit_damping`'s criterion) on the windows of ``err`` (G + 1, W, 3). Each regime's
    mean error is a per-class sum over the windows (every decay at once)."""
    out = np.zeros(3, dtype=int)
    for k in range(3):
        ref = err[0, :, k]
        cls = regime_of(ref, regimes)
        q, inv = np.unique(cls, return_inverse=True)
        n = np.bincount(inv, minlength=q.size).astype(float)
        means = (err[:, :, k] @ (inv[:, None] == np.arange(q.size)).astype(float)) / n   # (G + 1, Q)
        worst = (means[1:] / np.maximum(means[0], 1e-300)).max(axis=1)
        out[k] = int(np.argmin(worst))
    return out


def regime_of(held_error: np.ndarray, regimes: int, edges_from: np.ndarray | None = None) -> np.ndarray:
    """Class 0..regimes-1 of each window by its held error, cut at the quantiles of
    ``edges_from`` (default ``held_error`` itself)."""
    ref = held_error if edges_from is None else edges_from
    edges = np.quantile(ref, np.arange(1, regimes) / regimes) if regimes > 1 else np.zeros(0)
    return np.digitize(held_error, edges)
