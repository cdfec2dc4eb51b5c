"""Synthetic flights with known dynamics for the dataset, alignment and prior tests.

``tilt_drag_flight`` integrates the paper's tilt-drag model for chosen attitude histories, so the
true accelerations are the model evaluated on the states (exact to the ODE tolerance).
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from droneid.logs.flight import Flight, Provenance, Signal
from droneid.core.frames import euler_to_quat, wrap_angle


def attitude(t):
    pitch = 0.15 * np.sin(0.7 * t) + 0.05 * np.sin(1.9 * t + 1.0)
    roll = 0.12 * np.sin(0.5 * t + 0.3) + 0.04 * np.sin(2.3 * t)
    yaw = 0.4 * t + 2.0 + 0.6 * np.sin(0.9 * t) + 0.3 * np.sin(0.37 * t)  # crosses +pi (wraps) a few times
    return roll, pitch, yaw


def tilt_accel(t, g=9.81):
    """Thrust-tilt accelerations (without drag) of the tilt-drag model along x and y."""
    roll, pitch, yaw = attitude(t)
    ax = g * np.cos(yaw) * np.tan(pitch) / np.cos(roll) + g * np.sin(yaw) * np.tan(roll)
    ay = g * np.sin(yaw) * np.tan(pitch) / np.cos(roll) - g * np.cos(yaw) * np.tan(roll)
    return ax, ay


def vz_true(t):
    return 0.3 * np.sin(0.8 * t) + 0.2 * np.sin(0.31 * t)


def tilt_drag_truth(t, k_D=0.35, g=9.81):
    """States and accelerations on stamps ``t``: dict of arrays (vx, vy, x, y, z, vz, *_dot)."""
    def rhs(tt, s):
        ax, ay = tilt_accel(tt, g)
        return [ax - k_D * s[0], ay - k_D * s[1], s[0], s[1]]

    sol = solve_ivp(rhs, (t[0], t[-1]), [0.5, -0.3, 0.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-12,
                    method="DOP853")
    vx, vy, x, y = sol.y
    ax, ay = tilt_accel(t, g)
    return {"vx": vx, "vy": vy, "x": x, "y": y, "z": 1.5 - 0.3 / 0.8 * np.cos(0.8 * t) - 0.2 / 0.31 * np.cos(0.31 * t),
            "vz": vz_true(t), "vx_dot": ax - k_D * vx, "vy_dot": ay - k_D * vy,
            "vz_dot": 0.3 * 0.8 * np.cos(0.8 * t) + 0.2 * 0.31 * np.cos(0.31 * t)}


def tilt_drag_flight(duration_s=30.0, rate_hz=100.0, k_D=0.35, g=9.81, noise=0.0, seed=0,
                     clock_shift_s=0.0, names=("vx", "vy", "vz", "x", "y", "z", "roll", "pitch", "yaw"),
                     quaternion=False, label="synthetic") -> Flight:
    """A flight following the tilt-drag model. ``noise``: std of white noise added to the
    velocities (m/s) and 1/10 of it to positions and angles. ``clock_shift_s``: the recording's
    clock reads true time minus this (so +shift aligns it)."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    truth = tilt_drag_truth(t, k_D, g)
    roll, pitch, yaw = attitude(t)
    truth.update(roll=roll, pitch=pitch, yaw=yaw)
    rng = np.random.default_rng(seed)
    sig = {}
    for n in names:
        v = np.asarray(truth[n], dtype=float).copy()
        unit = {"vx": "m/s", "vy": "m/s", "vz": "m/s"}.get(n, "rad" if n in ("roll", "pitch", "yaw") else "m")
        if noise:
            v = v + rng.normal(0.0, noise if unit == "m/s" else noise / 10, v.size)
        if n == "yaw":
            v = wrap_angle(v)
        sig[n] = Signal(n, t - clock_shift_s, v, unit, "synthetic")
    if quaternion:
        q = euler_to_quat(roll, pitch, yaw)
        for i, n in enumerate(("qw", "qx", "qy", "qz")):
            sig[n] = Signal(n, t - clock_shift_s, q[:, i], "1", "synthetic")
    return Flight(sig, Provenance(files=(f"{label}.csv",), format="synthetic"))
