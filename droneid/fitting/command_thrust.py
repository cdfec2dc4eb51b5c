"""The thrust of a command-driven vehicle's logged commands, as the thrust-curve stage fits it.

Per rotor i, the normalised command ``q_i`` (the prior's normalisation, times V/V_ref where the
battery compensation is tried) asks for the normalised speed ``w*_i = sqrt(f_e(q_i))``
(:func:`priors.thrust.rotor_speed`); the rotor's speed is the state with inertia, so it follows
through a first-order lag of time constant τ (:func:`lagged`), and the rotor delivers the thrust
fraction ``w_i²``. The vertical thrust per unit mass is then ``k_T·b_z·Σ w_i²`` (m/s²; ``b_z``
the world-z component of the body z axis, ``k_T`` the prior's nominal scale), the same law the
open-loop motor model runs (:class:`droneid.simulation.motor_model.MotorModel`). Nonlinear in e
wherever τ > 0, so the stage evaluates it per (τ, e) grid point.

The target is a difference of the logged velocity: on the dataset's grid of period Ts a central
difference is exactly the MEAN of the acceleration over [t − Ts, t + Ts]
(:func:`droneid.core.differentiation.averaging_window`). Compared with the thrust AT t, a shape
that curves the thrust (e) is biased by the window (measured on the bench_commands vehicles, noise
off, the true lag: e 0.0025 low with point values, exact with window means). So the thrust is
computed on a grid :data:`FINE_STEPS` times finer than Ts (the commands interpolated as every
input is) and its window mean taken at each dataset row; the drag column (linear in the velocity)
stays at t.

A logged velocity is itself an estimate. Where it is a least-squares slope of the positions over
±h (a motion-capture system's velocity; a Savitzky-Golay first derivative), it is the velocity
averaged with the weights ``h² − s²`` over ``|s| ≤ h``, and so is its difference: ``slope_s`` = h
convolves the fine thrust with that kernel before the window mean (:func:`slope_smoothed`).

At a segment's ends the difference is not that mean: ``numpy.gradient``'s one-sided second-order
difference ``(−3v₀ + 4v₁ − v₂)/2Ts`` is an extrapolation (``2·mean[0, Ts] − mean[0, 2Ts]``) with
3.6 times the noise of a central one, and a logged velocity that is a smoothed estimate is often
truncated there too. :func:`window_rows` marks the rows whose difference is the window mean; the
stage fits on those only (measured on the bench_commands vehicles: with the end rows the lag came
out 0.8 ms low on average over 18 noise realisations of 9 vehicles, without them +0.02 ms; the
lag's interval covered the planted lag on 13 of 20 vehicles with them, 17 of 20 without).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from priors.thrust import rotor_speed

__all__ = ["CommandThrust", "LinearThrust", "lagged", "slope_smoothed", "window_rows", "FINE_STEPS"]

#: fine-grid steps per dataset step Ts on which the thrust is computed before its window mean
FINE_STEPS = 5


def _segments(t: np.ndarray, flight: np.ndarray) -> np.ndarray:
    """Segment id of each row (rows ordered by flight, then time): a new segment at each flight's
    start and after a step over 1.5 median steps (a gap) or a non-positive one."""
    t = np.asarray(t, float)
    if t.size < 2:
        return np.zeros(t.size, int)
    dt = np.diff(t)
    step = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    new = np.concatenate([[True], (np.asarray(flight)[1:] != np.asarray(flight)[:-1]) | (dt > 1.5 * step) | (dt <= 0)])
    return np.cumsum(new) - 1


def window_rows(t: np.ndarray, flight: np.ndarray, window: tuple[float, float]) -> np.ndarray:
    """(rows,) bool: the rows (ordered by flight, then time ``t`` s, on a grid) whose window
    ``[t − before, t + after]`` (s; :func:`droneid.core.differentiation.averaging_window`) lies
    within their segment (:func:`_segments`): the rows whose difference IS the mean of the
    derivative over that window, not a one-sided difference at a segment's end."""
    t = np.asarray(t, float)
    if t.size == 0:
        return np.zeros(0, bool)
    seg = _segments(t, flight)
    first = np.concatenate([[True], seg[1:] != seg[:-1]])
    last = np.concatenate([seg[1:] != seg[:-1], [True]])
    start, end = t[first][seg], t[last][seg]
    dt = np.diff(t)
    tol = 1e-6 * (float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0)
    return (t - float(window[0]) >= start - tol) & (t + float(window[1]) <= end + tol)


def lagged(x: np.ndarray, t: np.ndarray, flight: np.ndarray, tau_s: float) -> np.ndarray:
    """``x`` (rows ordered by flight, then time ``t`` s; 1-D, or 2-D with one series per column)
    through a first-order lag of time constant ``tau_s``: dy/dt = (x − y)/τ, discretised exactly
    for x linear between rows (first-order hold: the rows are coarser than the lag). It restarts
    at y = x after a gap (a step over 1.5 median steps) and at each flight's start. τ = 0: ``x``."""
    x = np.asarray(x, float)
    if tau_s <= 0 or x.shape[0] < 2:
        return x.copy()
    from scipy.signal import lfilter

    t = np.asarray(t, float)
    seg = _segments(t, flight)
    X = x.reshape(x.shape[0], -1)
    y = np.empty_like(X)
    starts = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]]))
    for s0, s1 in zip(starts, [*starts[1:], x.shape[0]]):
        if s1 - s0 == 1:
            y[s0] = X[s0]
            continue
        h = np.diff(t[s0:s1])
        if np.ptp(h) <= 1e-9 * np.mean(h):    # a uniform segment: one linear filter
            a = np.exp(-h[0] / tau_s)
            c = tau_s / h[0] * (1.0 - a)
            # y_k = a y_{k-1} + (1 − c) x_k + (c − a) x_{k-1}, starting at y_0 = x_0
            y[s0:s1] = lfilter([1.0 - c, c - a], [1.0, -a], X[s0:s1], axis=0, zi=(c * X[s0])[None])[0]
            continue
        a = np.exp(-h / tau_s)
        c = tau_s / h * (1.0 - a)
        y[s0] = X[s0]
        for k in range(1, s1 - s0):
            i = s0 + k
            y[i] = a[k - 1] * y[i - 1] + X[i] - a[k - 1] * X[i - 1] - c[k - 1] * (X[i] - X[i - 1])
    return y.reshape(x.shape)


def slope_smoothed(x: np.ndarray, t: np.ndarray, flight: np.ndarray, half_s: float) -> np.ndarray:
    """``x`` (rows ordered by flight, then time ``t`` s, on a uniform grid within each segment;
    1-D or 2-D, one series per column) averaged as a least-squares slope over ±``half_s`` s
    averages a derivative: weights ``h² − s²`` for ``|s| ≤ h`` (h = ``half_s``; each row takes the
    kernel's integral over its own cell of one step), each segment (a flight, or the rows between
    gaps) on its own, its ends continued by their first and last values (how an estimator treats
    its ends, no log says). ``half_s`` of one step or less: ``x``."""
    from scipy.ndimage import convolve1d

    x = np.asarray(x, float)
    t = np.asarray(t, float)
    seg = _segments(t, flight)
    steps = np.diff(t)[seg[1:] == seg[:-1]]
    if half_s <= 0 or steps.size == 0:
        return x.copy()
    h = half_s / float(np.median(steps))                  # in steps
    if h <= 1.0:
        return x.copy()
    n = int(np.ceil(h - 0.5 - 1e-9))                       # the cells [j − ½, j + ½] within ±h
    s = np.arange(-n, n + 1, dtype=float)
    a, b = np.maximum(s - 0.5, -h), np.minimum(s + 0.5, h)
    k = h * h * (b - a) - (b ** 3 - a ** 3) / 3.0          # ∫ (h² − u²) du over each row's cell
    k /= k.sum()
    y = np.empty_like(x)
    starts = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]]))
    for s0, s1 in zip(starts, [*starts[1:], x.shape[0]]):
        y[s0:s1] = convolve1d(x[s0:s1], k, axis=0, mode="nearest")
    return y


@dataclass(frozen=True)
class LinearThrust:
    """A thrust column linear in the shape, ``(1 − e)·linear + e·quadratic`` (no lag): the
    thrust term at e = 0 and e = 1 on the rows, m/s² (for data given as columns)."""
    linear: np.ndarray
    quadratic: np.ndarray

    def __call__(self, expos, tau_s: float = 0.0) -> np.ndarray:
        e = np.atleast_1d(np.asarray(expos, float))
        if tau_s > 0:
            raise ValueError("a LinearThrust has no motor lag")
        return np.outer(self.linear, 1.0 - e) + np.outer(self.quadratic, e)


@dataclass(frozen=True)
class CommandThrust:
    """The vertical thrust per unit mass of the commands on a fine grid, as window means at the
    dataset's rows (see the module docstring); call it with shapes e and a lag τ.

    q : (n, M) normalised commands on the fine grid (voltage-scaled where tried)
    k : (n,) m/s² of one rotor at full thrust along world z, ``k_T·b_z``
    t, flight : (n,) the fine rows' times (s) and flights
    at : (rows, 2) the window [t − before, t + after] of each dataset row on the fine time axis,
        clamped to the fine segment holding the row (its ends as fine-row positions, fractional)
    slope_s : half-width h (s) of the least-squares slope the logged velocity is taken to be
        (0: the velocity as it is; :func:`slope_smoothed`)
    """
    q: np.ndarray
    k: np.ndarray
    t: np.ndarray
    flight: np.ndarray
    at: np.ndarray
    slope_s: float = 0.0

    @classmethod
    def build(cls, q, k, t, flight, rows_t, rows_flight, window: tuple[float, float],
              slope_s: float = 0.0) -> "CommandThrust":
        """From the fine rows (``q`` (n, M), ``k``, ``t`` s, ``flight``), the dataset rows' times
        and flights, the differentiator's ``window`` (before, after) s and the velocity's
        ``slope_s``."""
        t, flight = np.asarray(t, float), np.asarray(flight)
        seg = _segments(t, flight)
        span = 2.0 * (float(np.max(t)) - float(np.min(t)) + 1.0) if t.size else 1.0
        key = flight * span + t                              # one increasing axis over flights
        seg_lo = key[np.concatenate([[True], seg[1:] != seg[:-1]])]
        seg_hi = key[np.concatenate([seg[1:] != seg[:-1], [True]])]
        rkey = np.asarray(rows_flight) * span + np.asarray(rows_t, float)
        j = np.clip(np.searchsorted(key, rkey + 1e-9, side="right") - 1, 0, max(key.size - 1, 0))
        s = seg[j]
        lo = np.maximum(rkey - window[0], seg_lo[s])
        hi = np.minimum(rkey + window[1], seg_hi[s])
        pos = [np.interp(x, key, np.arange(key.size, dtype=float)) for x in (lo, hi)]
        return cls(np.asarray(q, float), np.asarray(k, float), t, flight, np.column_stack(pos), float(slope_s))

    def fine(self, expos, tau_s: float) -> np.ndarray:
        """(n, E) the thrust per unit mass (m/s²) on the fine rows at each shape of ``expos``."""
        e = np.atleast_1d(np.asarray(expos, float))
        if tau_s <= 0 and np.all(self.q >= 0):   # no lag: Σ w² = Σ f_e(q), linear in e
            lin, quad = np.sum(self.q, axis=1), np.sum(self.q * self.q, axis=1)
            return self.k[:, None] * (np.outer(lin, 1.0 - e) + np.outer(quad, e))
        w = rotor_speed(self.q[:, None, :], e[None, :, None])                  # (n, E, M)
        w = lagged(w, self.t, self.flight, tau_s)
        return self.k[:, None] * np.einsum("nem,nem->ne", w, w)

    def __call__(self, expos, tau_s: float = 0.0) -> np.ndarray:
        """(rows, E): the window mean of :meth:`fine` (through the velocity's slope) at each
        dataset row (m/s²)."""
        F = slope_smoothed(self.fine(expos, tau_s), self.t, self.flight, self.slope_s)
        seg = _segments(self.t, self.flight)
        inc = np.zeros_like(F)
        same = seg[1:] == seg[:-1]
        inc[1:] = np.where(same[:, None], 0.5 * (F[1:] + F[:-1]) * np.diff(self.t)[:, None], 0.0)
        C = np.cumsum(inc, axis=0)

        def at(A, pos):
            i = np.clip(np.floor(pos).astype(int), 0, A.shape[0] - 1)
            i1 = np.minimum(i + 1, A.shape[0] - 1)
            f = (pos - i)[:, None]
            return A[i] + f * (A[i1] - A[i])

        lo, hi = self.at[:, 0], self.at[:, 1]
        tl, th = np.interp(lo, np.arange(self.t.size), self.t), np.interp(hi, np.arange(self.t.size), self.t)
        width = (th - tl)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            mean = (at(C, hi) - at(C, lo)) / width
        return np.where(width > 1e-9, mean, at(F, lo))
