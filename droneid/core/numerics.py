"""Small numerical helpers shared by the engine, identification, prediction and diagnosis."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["rmse", "lstsq", "finite_median", "to_float"]


def rmse(a, b) -> float:
    """Root-mean-square of ``a - b`` (their units); nan for empty input."""
    d = np.asarray(a, float) - np.asarray(b, float)
    return float(np.sqrt(np.mean(d * d))) if d.size else float("nan")


def to_float(v) -> float:
    """``float(v)``, or NaN for None and what is not a number (results hold None for "not measured")."""
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def finite_median(values) -> float:
    """Median of the finite numbers among ``values`` (None, NaN and inf skipped); NaN for none."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], float)
    return float(np.median(v)) if v.size else float("nan")


def lstsq(A: np.ndarray, y: np.ndarray, rcond: float = 1e-12) -> np.ndarray:
    """Least squares on column-normalised ``A``: singular values below ``rcond`` (relative) are
    cut, so collinear or duplicate columns get a minimum-norm share instead of an error; zero
    columns get 0. Never raises (an SVD failure returns zeros)."""
    A = np.asarray(A, float)
    if A.shape[1] == 0:
        return np.zeros(0)
    norms = np.sqrt((A * A).sum(axis=0))
    norms[norms == 0] = 1.0
    try:
        beta, *_ = np.linalg.lstsq(A / norms, y, rcond=rcond)
    except np.linalg.LinAlgError:
        return np.zeros(A.shape[1])
    return beta / norms


def rounded(x, nd: int = 3) -> float | None:
    """``x`` rounded to ``nd`` decimals for a report, or None when it is missing or not finite."""
    return None if x is None or not math.isfinite(x) else round(float(x), nd)
