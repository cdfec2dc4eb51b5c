"""Signals put side by side on a common uniform grid, for checks that relate one signal to another
(:mod:`droneid.logs.consistency`): the grid step, the stretches where every signal has data, moving
averages, derivatives and lags on that grid. Times in s."""
from __future__ import annotations

import math

import numpy as np

from droneid.core.differentiation import CentralDifference
from droneid.logs.flight import Flight
from droneid.logs.in_flight import _intersect, resample_signal

__all__ = ["step_of", "grids", "smooth", "window", "on_grid", "lag_of", "rate_of"]


def step_of(flight: Flight, names) -> float:
    """The coarsest median sample step (s) of ``names``; NaN for a damaged log (a signal with
    fewer than 2 samples, or stamps that do not advance): no grid then."""
    d = [np.diff(flight[n].t) for n in names]
    h = max(float(np.median(x)) for x in d) if d and all(x.size for x in d) else math.nan
    return h if h > 0 else math.nan


def grids(flight: Flight, names, h: float, k: int) -> list[np.ndarray]:
    """Uniform grids of step ``h`` over where every signal of ``names`` has data (its bursts),
    each long enough for a smoothing window of ``k`` samples and a derivative (none when the step
    is not a positive number: a damaged log)."""
    if not (math.isfinite(h) and h > 0):
        return []
    ivs = [(flight.start_s, flight.end_s)]
    for n in names:
        ivs = _intersect(ivs, flight[n].bursts(max_gap_s=max(0.5, 3 * h)))
    return [np.arange(a, b + 1e-9 * h, h) for a, b in ivs if (b - a) / h >= 2 * k + 3]


def smooth(x: np.ndarray, k: int) -> np.ndarray:
    """Moving average over ``k`` samples; the k//2 samples at each end are nan."""
    if k <= 1:
        return x
    out = np.convolve(x, np.ones(k) / k, mode="same")
    out[: k // 2] = np.nan
    out[len(out) - k // 2:] = np.nan
    return out


def window(h: float, seconds: float) -> int:
    """Samples of a moving average of ``seconds`` at step ``h`` (at least 3)."""
    return max(3, int(round(seconds / h))) if math.isfinite(h) and h > 0 else 3


def on_grid(flight, name, t, angle=False):
    v = resample_signal(flight[name], t)
    return np.unwrap(v) if angle else v


def lag_of(meas: np.ndarray, ref: np.ndarray, h: float, max_s: float = 0.5) -> float:
    """The delay (s) of ``meas`` behind ``ref`` that correlates best, within ±``max_s`` (in grid
    steps ``h``): reported, never named (no reader option shifts one signal)."""
    m, r = (np.nan_to_num(x - np.nanmedian(x)) for x in (meas, ref))
    n = min(max(1, int(round(max_s / h))), len(m) // 4)
    c = [np.corrcoef(m[n + j:len(m) - n + j], r[n:len(r) - n])[0, 1] for j in range(-n, n + 1)]
    return (int(np.nanargmax(c)) - n) * h if np.isfinite(c).any() else math.nan


def rate_of(flight, name, t, k):
    """d(name)/dt on the grid ``t`` (central differences), smoothed over ``k`` samples."""
    return smooth(CentralDifference()(np.nan_to_num(on_grid(flight, name, t)), t), k)
