"""Numeric helpers the effects use on signals (one flight or several, on the dataset grid).

:func:`time_derivative` (d/dt inside each flight's contiguous runs, optionally smoothed),
:func:`spread` and :func:`high` (robust range and reach of a signal, for the effects'
preconditions, so a few outliers cannot make an effect testable). Re-exported by
:mod:`priors.effects`.
"""
from __future__ import annotations

import numpy as np

__all__ = ["time_derivative", "spread", "high"]


def time_derivative(x: np.ndarray, t: np.ndarray, flight: np.ndarray,
                    half_window_s: float = 0.0) -> np.ndarray:
    """d/dt of ``x`` inside each flight's contiguous runs of samples.

    A run breaks where the time step exceeds 1.5× the median step (trimmed gaps). With
    ``half_window_s`` = 0: central differences (one-sided at run ends). Otherwise the slope of a
    least-squares line over ±k samples, k = round(half_window_s / step) (a Savitzky-Golay
    derivative: same phase as central differences, much less noise gain), central differences
    within k samples of a run end.
    """
    x = np.asarray(x, float)
    t = np.asarray(t, float)
    out = np.zeros_like(x)
    if x.size < 2:
        return out
    dt = np.diff(t)
    med = np.median(dt[dt > 0]) if np.any(dt > 0) else 1.0
    brk = np.flatnonzero((np.diff(flight) != 0) | (dt > 1.5 * med) | (dt <= 0)) + 1
    k = int(round(half_window_s / med)) if half_window_s > 0 else 0
    for seg in np.split(np.arange(x.size), brk):
        if seg.size < 2:
            continue
        xs = x[seg]
        d = np.gradient(xs, t[seg])
        if k >= 1 and seg.size > 2 * k + 1:
            j = np.arange(-k, k + 1)
            c = j / (med * np.sum(j * j))
            d[k:-k] = np.convolve(xs, c[::-1], mode="valid")
        out[seg] = d
    return out


def spread(x, lo: float = 2.0, hi: float = 98.0) -> float:
    """Robust range of ``x``: its ``hi`` minus its ``lo`` percentile (0 for no data). Effects'
    preconditions (``data_fn``) use it so a few outliers cannot make an effect testable."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.percentile(x, hi) - np.percentile(x, lo)) if x.size else 0.0


def high(x, q: float = 98.0) -> float:
    """The ``q`` percentile of |x| (0 for no data): how far a signal robustly reaches."""
    x = np.abs(np.asarray(x, float))
    x = x[np.isfinite(x)]
    return float(np.percentile(x, q)) if x.size else 0.0

