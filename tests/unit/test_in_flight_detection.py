"""Hovering is flying (issue 25 item 5): a vehicle holding position in the air is airborne, even
at the lowest height of its flight; ground contact is found only where the vehicle rests (before a
take-off, after a landing)."""
from __future__ import annotations

import numpy as np

from droneid.dataset.builder import in_flight_intervals
from droneid.logs.flight import Flight, Signal


def _stop_and_go(take_off: bool) -> Flight:
    """Legs between 1.4 and 1.9 m with 0.4 s hovers (still, at hover power) between them; with
    ``take_off``, 3 s resting on the ground (idle) before and after."""
    t = np.arange(0.0, 30.0, 0.01)
    leg = 2.0                                   # s per leg: 1.6 s moving, 0.4 s hovering
    phase = (t % leg) / leg
    k = (t // leg).astype(int)
    lo, hi = 1.4, 1.9
    start = np.where(k % 2 == 0, lo, hi)
    end = np.where(k % 2 == 0, hi, lo)
    s = np.clip(phase / 0.8, 0, 1)
    shape = s * s * (3 - 2 * s)                 # smooth move, then a hold
    z = start + (end - start) * shape
    x = 0.5 * k + 0.5 * shape
    power = np.full(t.size, 0.5)
    if take_off:
        ground = (t < 3.0) | (t > 27.0)
        ramp = np.clip(np.minimum(t - 3.0, 27.0 - t) / 1.0, 0, 1)
        z = np.where(ground, 0.05, 0.05 + (z - 0.05) * ramp)
        x = np.where(ground, x[np.argmax(~ground)] if (~ground).any() else 0.0, x)
        power = np.where(ground, 0.05, power)
    vx, vz = np.gradient(x, t), np.gradient(z, t)
    sig = lambda n, v, u: Signal(n, t, v, u)  # noqa: E731
    return Flight({"x": sig("x", x, "m"), "y": sig("y", 0 * t, "m"), "z": sig("z", z, "m"),
                   "vx": sig("vx", vx, "m/s"), "vy": sig("vy", 0 * t, "m/s"), "vz": sig("vz", vz, "m/s"),
                   "throttle": sig("throttle", power, "1")})


def test_hovers_at_altitude_are_airborne():
    f = _stop_and_go(take_off=False)
    ivs, notes = in_flight_intervals(f)
    assert ivs == [(f.start_s, f.end_s)], notes


def test_take_off_and_landing_are_cut_and_the_hovers_between_kept():
    f = _stop_and_go(take_off=True)
    ivs, notes = in_flight_intervals(f)
    assert len(ivs) == 1, notes                       # one airborne stretch: no hover cut out
    a, b = ivs[0]
    assert 3.0 < a < 3.6 and 26.4 < b < 27.0, (a, b)  # ground + margin trimmed at both ends
