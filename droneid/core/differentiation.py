"""Numerical differentiators: the derivative targets (``vx_dot`` ...) are made here.

One base class, :class:`Differentiator`, whose public ``__call__(x, t)`` validates the input
and whose subclasses only implement ``_impl``. Pick one by name with :func:`get_differentiator`:

``forward``
    The paper's forward difference, ``x_dot[k] = (x[k+1] - x[k]) / (t[k+1] - t[k])``, assigned to
    sample ``k``. The last sample has no successor and is ``nan`` (the dataset builder drops it).
    Error O(Ts) on smooth signals; noise is amplified by ``sqrt(2)/Ts``.
``central``
    Second-order central differences (``numpy.gradient``, second-order one-sided at the ends).
    Error O(Ts²) on smooth signals, works on non-uniform stamps.
``savgol``
    Savitzky-Golay: a local polynomial of degree ``polyorder`` fitted over ``window_s`` seconds,
    differentiated analytically (``scipy.signal.savgol_filter``). Needs uniform stamps. For
    noisy logs.
``spline``
    A smoothing spline (``scipy.interpolate.make_smoothing_spline``) differentiated
    analytically. ``window_s=None`` lets generalised cross-validation choose the smoothing; a
    ``window_s`` sets the penalty so that wavelengths shorter than about ``window_s`` are
    suppressed. Works on non-uniform stamps. For noisy logs.

``smoothing`` is True for the last two: the dataset builder then differentiates at the signal's
native rate and samples the derivative on its grid, instead of differentiating on the grid.
"""
from __future__ import annotations

import math

import numpy as np

from droneid.errors import ConfigError, DataError, check_choice

__all__ = ["Differentiator", "ForwardDifference", "CentralDifference", "SavitzkyGolay",
           "SmoothingSpline", "DIFFERENTIATORS", "get_differentiator", "averaging_window"]


class Differentiator:
    """Base class: ``d(x, t) -> x_dot`` with ``x`` and ``t`` 1-D float arrays of equal length.

    The public :meth:`__call__` checks shapes, finiteness, strictly increasing ``t`` and the
    minimum number of samples; subclasses implement only :meth:`_impl`.
    """

    #: name in :data:`DIFFERENTIATORS`
    name = "base"
    #: True when the method smooths (then it is best applied at the native sample rate)
    smoothing = False
    #: fewest samples the method accepts
    min_samples = 2

    def __call__(self, x, t) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        t = np.asarray(t, dtype=np.float64)
        if x.ndim != 1 or t.shape != x.shape:
            raise DataError(f"{self.name} differentiator: x and t must be 1-D of equal length, "
                            f"got {x.shape} and {t.shape}")
        if x.size < self.min_samples:
            raise DataError(f"{self.name} differentiator needs at least {self.min_samples} samples, "
                            f"got {x.size}")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(t))):
            raise DataError(f"{self.name} differentiator: x and t must be finite "
                            f"({int((~np.isfinite(x)).sum())} non-finite values)")
        if not np.all(np.diff(t) > 0):
            raise DataError(f"{self.name} differentiator: t must be strictly increasing")
        return self._impl(x, t)

    def _impl(self, x: np.ndarray, t: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in vars(self).items())
        return f"{type(self).__name__}({params})"


class ForwardDifference(Differentiator):
    """``x_dot[k] = (x[k+1] - x[k]) / (t[k+1] - t[k])``; the last sample is nan (the paper's)."""
    name = "forward"

    def _impl(self, x, t):
        out = np.full_like(x, np.nan)
        out[:-1] = np.diff(x) / np.diff(t)
        return out


class CentralDifference(Differentiator):
    """Second-order central differences, second-order one-sided at both ends."""
    name = "central"
    min_samples = 3

    def _impl(self, x, t):
        return np.gradient(x, t, edge_order=2)


def _check_window(window_s):
    if window_s is not None and not (isinstance(window_s, (int, float)) and math.isfinite(window_s)
                                     and window_s > 0):
        raise ConfigError(f"The 'window_s' parameter must be a positive number of seconds or None. "
                          f"Got {window_s!r} instead.")


class SavitzkyGolay(Differentiator):
    """Savitzky-Golay derivative over a window of ``window_s`` seconds (odd sample count,
    at least ``polyorder + 2``). Needs uniform stamps (relative spread of steps below 1 %)."""
    name = "savgol"
    smoothing = True

    def __init__(self, window_s: float | None = 0.25, polyorder: int = 2):
        _check_window(window_s)
        if not isinstance(polyorder, int) or polyorder < 1:
            raise ConfigError(f"The 'polyorder' parameter of savgol must be an integer >= 1. "
                              f"Got {polyorder!r} instead.")
        self.window_s = 0.25 if window_s is None else float(window_s)
        self.polyorder = polyorder

    @property
    def min_samples(self):  # noqa: D401 - property overrides the class attribute
        return self.polyorder + 2

    def _impl(self, x, t):
        from scipy.signal import savgol_filter
        dt = np.diff(t)
        h = float(np.median(dt))
        if np.max(np.abs(dt - h)) > 0.01 * h:
            raise DataError("savgol differentiator needs uniformly spaced samples "
                            f"(steps from {dt.min():.6g} to {dt.max():.6g} s); resample first")
        n = int(round(self.window_s / h))
        n = max(n | 1, self.polyorder + 2 if (self.polyorder + 2) % 2 else self.polyorder + 3)
        if n > x.size:
            n = x.size if x.size % 2 else x.size - 1
        if n <= self.polyorder:
            raise DataError(f"savgol differentiator: {x.size} samples are too few for "
                            f"polyorder {self.polyorder}")
        return savgol_filter(x, n, self.polyorder, deriv=1, delta=h, mode="interp")


class SmoothingSpline(Differentiator):
    """Derivative of a cubic smoothing spline. ``window_s=None``: smoothing chosen by
    generalised cross-validation; otherwise ``lam = (window_s / 2π)⁴ / h`` (h: mean step), which
    puts the spline's half-power wavelength near ``window_s``."""
    name = "spline"
    smoothing = True
    min_samples = 5

    def __init__(self, window_s: float | None = None):
        _check_window(window_s)
        self.window_s = None if window_s is None else float(window_s)

    def _impl(self, x, t):
        from scipy.interpolate import make_smoothing_spline
        lam = None
        if self.window_s is not None:
            h = float((t[-1] - t[0]) / (t.size - 1))
            lam = (self.window_s / (2 * math.pi)) ** 4 / h
        # centre and scale for conditioning; the derivative scales back
        t0, x0 = t[0], float(np.mean(x))
        spl = make_smoothing_spline(t - t0, x - x0, lam=lam)
        return spl.derivative()(t - t0)


#: name -> class
DIFFERENTIATORS = {
    "forward": ForwardDifference,
    "central": CentralDifference,
    "savgol": SavitzkyGolay,
    "spline": SmoothingSpline,
}


def averaging_window(method: str, ts: float) -> tuple[float, float]:
    """(before, after) in s: on a grid of period ``ts`` s a difference of the differentiator
    ``method`` is exactly the mean of the true derivative over ``[t − before, t + after]``
    (``central``: ``(x[k+1] − x[k−1]) / 2Ts``, the mean over ±Ts; ``forward``: over the next step).
    A model compared with such a target without this window is compared with another quantity (a
    second-order error ``window²/6 · x⃛`` that can bias a nonlinear parameter). The smoothing
    methods work at the native rate with a data-dependent kernel: (0, 0), the point value."""
    return {"central": (float(ts), float(ts)), "forward": (0.0, float(ts))}.get(method, (0.0, 0.0))


def get_differentiator(name: str, **params) -> Differentiator:
    """A differentiator by name (``forward``, ``central``, ``savgol``, ``spline``).

    ``params`` go to its constructor (``window_s`` for savgol and spline, ``polyorder`` for
    savgol); a parameter the method does not take raises :class:`ConfigError`.
    """
    check_choice("method", name, DIFFERENTIATORS, owner="the differentiator")
    cls = DIFFERENTIATORS[name]
    import inspect
    accepted = [p for p in inspect.signature(cls.__init__).parameters if p != "self"] \
        if cls.__init__ is not object.__init__ else []
    unknown = [k for k in params if k not in accepted]
    if unknown:
        raise ConfigError(f"the {name!r} differentiator takes no parameter {unknown[0]!r} "
                          f"(it takes: {', '.join(accepted) or 'none'})")
    return cls(**params)
