"""Physical sanity checks on converted flights (shared by the real-log tests and the benchmarks)."""
from __future__ import annotations

import numpy as np

G = 9.81


def tilt_drag_coefficients(ds, target: str) -> np.ndarray:
    """Least-squares coefficients of the tilt-drag prior's three features plus an intercept on a
    :class:`~droneid.dataset.data.Dataset` for ``target`` (``vx_dot`` or ``vy_dot``): about (1, 1, k_D/0.28,
    0) for a flight that obeys the model with drag coefficient k_D."""
    from priors.registry import get_prior
    F = get_prior("tilt-drag").evaluate(ds.columns(), target, 3)
    A = np.column_stack([F, np.ones(len(ds))])
    return np.linalg.lstsq(A, ds.y, rcond=None)[0]


def _interp(sig, t):
    return np.interp(t, sig.t, sig.values)


def tilt_drag_correlation(flight, *, rate_hz: float = 10.0, smooth_s: float = 0.3,
                          windows=None) -> tuple[float, float, int]:
    """Pearson correlation of the measured world horizontal acceleration (d/dt of vx, vy after a
    light moving-average smoothing, on a common grid) with the tilt-drag model's gravity terms
    g(cosψ tanθ/cosφ + sinψ tanφ) (x) and g(sinψ tanθ/cosφ − cosψ tanφ) (y).

    ``windows``: (t0, t1) intervals to use (default: the flight's in_flight segments, else all).
    Returns (corr_x, corr_y, n_samples).
    """
    if windows is None:
        windows = flight.segments.get("in_flight") or ((flight.start_s, flight.end_s),)
    need = ("vx", "vy", "roll", "pitch", "yaw")
    lo = max(flight[n].start_s for n in need)
    hi = min(flight[n].end_s for n in need)
    dt = 1.0 / rate_hz
    k = max(1, int(round(smooth_s * rate_hz)))
    mx, my, gx, gy = [], [], [], []
    for a, b in windows:
        a, b = max(a, lo), min(b, hi)
        if b - a < 10 * dt + 2 * smooth_s:
            continue
        t = np.arange(a, b, dt)
        kern = np.ones(k) / k
        vx = np.convolve(_interp(flight["vx"], t), kern, mode="same")
        vy = np.convolve(_interp(flight["vy"], t), kern, mode="same")
        ax, ay = np.gradient(vx, dt), np.gradient(vy, dt)
        phi, th = _interp(flight["roll"], t), _interp(flight["pitch"], t)
        yaw = flight["yaw"]
        c = np.interp(t, yaw.t, np.cos(yaw.values))
        s = np.interp(t, yaw.t, np.sin(yaw.values))
        n = np.hypot(c, s)
        c, s = c / n, s / n
        sl = slice(k, -k if k else None)  # drop the smoothing edges
        mx.append(ax[sl]), my.append(ay[sl])
        gx.append((G * (c * np.tan(th) / np.cos(phi) + s * np.tan(phi)))[sl])
        gy.append((G * (s * np.tan(th) / np.cos(phi) - c * np.tan(phi)))[sl])
    mx, my, gx, gy = (np.concatenate(v) if v else np.array([]) for v in (mx, my, gx, gy))
    if mx.size < 10:
        return float("nan"), float("nan"), int(mx.size)
    return float(np.corrcoef(mx, gx)[0, 1]), float(np.corrcoef(my, gy)[0, 1]), int(mx.size)
