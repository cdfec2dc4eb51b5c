"""Helpers shared by the log writers: sampling a flight's signals on one time base."""
from __future__ import annotations

import numpy as np

from droneid.errors import DataError
from droneid.logs.flight import Signal
from droneid.core.frames import euler_to_quat, quat_to_euler, unwrap_angle, wrap_angle

#: fixed epoch of written logs (2024-01-01 00:00:00 UTC): outputs never depend on the clock
EPOCH_S = 1_704_067_200
EPOCH_US = EPOCH_S * 1_000_000
EPOCH_NS = EPOCH_S * 1_000_000_000

_ANGLES = ("roll", "pitch", "yaw")


def group(flight, names, required=None):
    """Signals ``names`` of ``flight`` on the time base of the first present required one.

    Returns ``(t, {name: values})`` or ``None`` when a required signal is missing. Signals on
    other time bases are interpolated (angles unwrapped first); missing optional ones are NaN.
    """
    required = names if required is None else required
    if not all(flight.has(n) for n in required):
        return None
    base = next((n for n in names if flight.has(n)), None)
    if base is None:
        return None
    t = flight[base].t
    out = {}
    for n in names:
        if not flight.has(n):
            out[n] = np.full(t.size, np.nan)
            continue
        s = flight[n]
        if s.t.size == t.size and np.array_equal(s.t, t):
            out[n] = s.values
        elif n in _ANGLES:
            out[n] = wrap_angle(np.interp(t, s.t, unwrap_angle(s.values)))
        else:
            out[n] = np.interp(t, s.t, s.values)
    return t, out


def require_some(flight, path, what):
    if not flight.signals:
        raise DataError(f"cannot write {path}: the flight has no signals ({what})")


def complete_attitude(flight):
    """The flight with Euler angles derived from the quaternion, or the quaternion from the
    Euler angles, where only one of them is present (formats need both)."""
    euler, quat = ("roll", "pitch", "yaw"), ("qw", "qx", "qy", "qz")
    if flight.has(*quat) and not flight.has(*euler):
        t, v = group(flight, quat)
        r, p, y = quat_to_euler(np.column_stack([v[n] for n in quat]))
        return flight.with_signals(*(Signal(n, t, a, "rad", "derived from qw..qz")
                                     for n, a in zip(euler, (r, p, y))))
    if flight.has(*euler) and not flight.has(*quat):
        t, v = group(flight, euler)
        q = euler_to_quat(v["roll"], v["pitch"], v["yaw"])
        q = np.where(q[:, :1] < 0, -q, q)
        return flight.with_signals(*(Signal(n, t, q[:, k], "1", "derived from roll/pitch/yaw")
                                     for k, n in enumerate(quat)))
    return flight
