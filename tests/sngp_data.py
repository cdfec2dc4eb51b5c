"""Drone-like regression data with a planted tilt-drag law, shared by the SNGP tests."""
from __future__ import annotations

import numpy as np

G, KD = 9.81, 0.28
NAMES = ["vx", "pitch", "roll", "yaw"]
TILT_DRAG_3 = ["9.81*cos(yaw)*tan(pitch)/cos(roll)", "9.81*sin(yaw)*tan(roll)", "-0.28*vx"]


def tilt_drag(vx, pitch, roll, yaw):
    return G * np.cos(yaw) * np.tan(pitch) / np.cos(roll) + G * np.sin(yaw) * np.tan(roll) - KD * vx


def flight_data(n=160, seed=0, extra=0.0, noise=0.0):
    """Drone-like smooth inputs along an eight; vx_dot from tilt-drag (+ extra*|vx|*vx)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 16, n)
    vx = 1.5 * np.sin(0.8 * t) + 0.1 * rng.normal(size=n)
    pitch = 0.2 * np.sin(0.8 * t + 0.4)
    roll = 0.15 * np.sin(1.6 * t)
    yaw = 0.6 * np.sin(0.3 * t) + 0.2
    y = tilt_drag(vx, pitch, roll, yaw) + extra * np.abs(vx) * vx + noise * rng.normal(size=n)
    return np.c_[vx, pitch, roll, yaw], y
