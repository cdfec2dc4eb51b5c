"""The rotor-torque layouts and the vehicle model of droneid.rotation.model recover planted truth:
synthetic flights simulated open loop from known coefficients (issue 28). The fits share one
simulated-flight fixture (about 10 s to build): those tests are marked slow."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from droneid.errors import ConfigError
from droneid.simulation.openloop import StateLog, open_loop, simulate
from droneid.rotation.model import (RotationModel, TranslationModel, VehicleModel, centred, fit_rotation,
                              fit_translation, flying_segments, identify_layout)
from droneid.rotation.choice import fit_rotation_multistep
from priors.torque import LAYOUTS, RotorLayout, get_layout

DT = 0.01
#: planted rotation: per axis [pattern, centre, damping, (spinup)]
TRUE_COEF = (np.array([6.0, 0.05, 4.0]), np.array([5.0, -0.03, 4.0]), np.array([1.5, 0.02, 4.0, 0.5]))
TRUE_TRANSLATION = TranslationModel(k_thrust=0.83, drag=np.array([0.3, 0.2, 0.1]))


def _smooth_noise(rng, n, m, scale, width=15):
    x = rng.standard_normal((n + 4 * width, m))
    k = np.hanning(2 * width + 1)
    k /= k.sum()
    y = np.column_stack([np.convolve(x[:, j], k, mode="same") for j in range(m)])[2 * width:2 * width + n]
    return scale * y / y.std(axis=0)


def _flight(seed, trim, n=1500, coef=TRUE_COEF, name="synthetic"):
    """A flight simulated from the planted model with the motor speeds of a noisy hover."""
    rng = np.random.default_rng(seed)
    rpm = 95000.0 + _smooth_noise(rng, n, 4, 3000.0)
    rot = RotationModel(get_layout("crazyflie_x"), ("centre", "damping", "spinup"), coef, np.asarray(trim, float))
    truth = VehicleModel(TRUE_TRANSLATION, rot)
    dummy = StateLog(name, DT * np.arange(n), np.zeros((n, 13)), rpm, DT)
    u = truth.inputs(dummy)
    x0 = np.array([0, 0, 100.0, 0, 0, 0, 1, 0, 0, 0, 0.2, -0.1, 0.0])
    states = np.vstack([x0, simulate(truth, x0[None], u[None, :-1], DT)[0]])
    return StateLog(name, DT * np.arange(n), states, rpm, DT)


@pytest.fixture(scope="module")
def flights():
    return [_flight(1, [0.5, -0.3, 0.1]), _flight(2, [-0.5, 0.1, -0.1])]


def test_every_layout_gives_no_torque_at_equal_speeds():
    for layout in LAYOUTS.values():
        layout.check()
        np.testing.assert_allclose(layout.mix(np.ones(layout.motors)), 0.0, atol=1e-12)
    bad = RotorLayout("bad", x=(1.0, -1.0, 1.0, -1.0), y=(1.0, 1.0, 1.0, -1.0), spin=(1, -1, 1, -1))
    with pytest.raises(ConfigError, match="roll"):
        bad.check()
    with pytest.raises(ConfigError, match="crazyflie_x"):
        get_layout("crazyflie")


def test_crazyflie_layout_is_the_benchmark_mixer():
    p = get_layout("crazyflie_x").patterns()
    np.testing.assert_array_equal(np.sign(p), [[-1, -1, 1, 1], [-1, 1, 1, -1], [-1, 1, -1, 1]])


@pytest.mark.slow   # shares a 10 s simulated-flight fixture
def test_equation_error_fit_recovers_the_planted_rotation(flights):
    m = fit_rotation(flights, terms=("centre", "damping", "spinup"), window_s=0.05)
    for k in range(3):
        np.testing.assert_allclose(m.coef[k], TRUE_COEF[k], rtol=0.05, atol=0.01)
    np.testing.assert_allclose(m.flight_trims, [[0.5, -0.3, 0.1], [-0.5, 0.1, -0.1]], atol=0.1)


@pytest.mark.slow   # shares a 10 s simulated-flight fixture
def test_multistep_fit_recovers_the_planted_rotation_and_damping(flights):
    m = fit_rotation_multistep(flights, damping_grid=(0.0, 2.0, 4.0, 8.0), stride=10)
    for k in range(3):
        np.testing.assert_allclose(m.coef[k], TRUE_COEF[k], rtol=0.02, atol=0.005)
    np.testing.assert_allclose(m.trim, [0.0, -0.1, 0.0], atol=0.02)


@pytest.mark.slow   # shares a 10 s simulated-flight fixture
def test_translation_fit_recovers_thrust_and_drag_with_gravity_fixed(flights):
    m = fit_translation(flights, window_s=0.05)
    assert m.k_thrust == pytest.approx(0.83, rel=0.01)
    np.testing.assert_allclose(m.drag, [0.3, 0.2, 0.1], atol=0.03)
    assert m.g == 9.81


@pytest.mark.slow   # shares a 10 s simulated-flight fixture
def test_identify_layout_finds_the_sign_pattern(flights):
    signs, _ = identify_layout(flights, rad_s_per_rpm=2 * np.pi / 360)
    np.testing.assert_array_equal(signs, np.sign(get_layout("crazyflie_x").patterns()))


@pytest.mark.slow   # shares a 10 s simulated-flight fixture
def test_the_planted_model_beats_a_wrong_one_open_loop(flights):
    rot = fit_rotation_multistep(flights, damping_grid=(0.0, 2.0, 4.0, 8.0), stride=10)
    good = VehicleModel(fit_translation(flights), rot)
    flipped = tuple(c * np.r_[-1.0, np.ones(c.size - 1)] for c in rot.coef)   # torques reversed
    wrong = VehicleModel(good.translation, dataclasses.replace(rot, coef=flipped))
    res = open_loop({"good": good, "wrong": wrong}, flights, stride=25)
    for q in ("attitude", "rates"):
        assert res["good"].simerr[q] < 0.5 * res["wrong"].simerr[q]


def test_flying_segments_cut_out_stopped_motors():
    log = _flight(3, [0, 0, 0], n=600)
    rpm = log.rpm.copy()
    rpm[200:300] = 0.0
    cut = StateLog("cut", log.t_s, log.state, rpm, DT)
    segs = flying_segments(cut, min_steps=100)
    assert [len(s) for s in segs] == [200, 300]


def test_centring_is_causal_and_removes_a_flight_offset():
    rng = np.random.default_rng(4)
    s = 2.0 + 0.1 * rng.standard_normal((2000, 4))
    c = centred(s + np.array([0.3, -0.2, 0.0, 0.1]), DT, 1.0)
    np.testing.assert_allclose(c[1000:].mean(axis=0), 0.0, atol=0.02)   # after ~10 time constants
    later = s.copy()
    later[1500:] += 5.0
    np.testing.assert_array_equal(centred(later, DT, 1.0)[:1500], centred(s, DT, 1.0)[:1500])
    assert centred(s, DT, None) is s
