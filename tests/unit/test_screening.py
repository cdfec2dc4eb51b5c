"""Screening of implausible samples (droneid.logs.screening): the documented rule finds planted
glitches and leaves clean signals alone; inspect counts what it finds."""
from __future__ import annotations

import numpy as np

from droneid.logs.flight import Flight, Signal
from droneid.logs.screening import JUMP_FACTOR, screen_signal


def _rpm(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    v = 15000 + 3000 * np.sin(2 * np.pi * t / 3.0) + 200 * rng.standard_normal(n)
    return t, v


def test_a_clean_signal_is_left_alone():
    t, v = _rpm()
    sc = screen_signal(Signal("rpm1", t, v, "rpm"))
    assert sc.implausible == 0 and sc.holes == ()


def test_spikes_far_beyond_the_range_are_found_with_their_holes():
    t, v = _rpm()
    v[[500, 1500, 2500]] = v.max() * np.array([10, 25, 40])
    sc = screen_signal(Signal("rpm1", t, v, "rpm"))
    assert sc.out_of_range == 3
    for i in (500, 1500, 2500):   # every hole covers its sample and stops at the neighbours
        assert any(a <= t[i - 1] and t[i + 1] <= b and b - a < 0.05 for a, b in sc.holes)


def test_a_negative_motor_speed_is_physically_impossible():
    t, v = _rpm()
    v[100] = -5.0
    assert screen_signal(Signal("rpm2", t, v, "rpm")).out_of_range == 1


def test_a_mocap_jump_is_a_jump_and_its_cluster_one_hole():
    t = np.arange(2000) * 0.01
    z = 1.0 + 0.3 * np.sin(2 * np.pi * t / 4.0)
    z[700:703] += 0.4                           # a marker swap: three samples 40 cm off
    sc = screen_signal(Signal("z", t, z, "m"))
    assert sc.jumps == 2 and len(sc.holes) == 1
    a, b = sc.holes[0]
    assert a < t[699] and b > t[703]
    # a fast but smooth manoeuvre is no jump: the rule is relative to the flight's own rates
    z2 = 1.0 + 0.3 * np.sin(2 * np.pi * t / 0.5)
    assert screen_signal(Signal("z", t, z2, "m")).jumps == 0
    assert JUMP_FACTOR > 1


def test_inspect_reports_implausible_samples():
    from droneid.commands.inspect import implausible_summary, render_text
    t, v = _rpm()
    v[1000] = v.max() * 20
    f = Flight({"rpm1": Signal("rpm1", t, v, "rpm")})
    bad = implausible_summary(f)
    assert bad["rpm1"]["count"] == 1 and "outside" in bad["rpm1"]["detail"]
    s = f.summary()
    s["implausible"] = bad
    assert "implausible: 1 sample(s) or jump(s) screened out" in render_text(s)
