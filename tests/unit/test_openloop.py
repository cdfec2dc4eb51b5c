"""The open-loop metric (issue 28) against hand-computed cases, and the RK4 simulator against
closed-form motions."""
from __future__ import annotations

import math

import numpy as np
import pytest

from droneid.errors import DataError
from droneid.logs.flight import Flight, Signal
from droneid.core.frames import qmul
from droneid.simulation.openloop import (QUANTITIES, Constant, NominalPhysics, StateLog, open_loop,
                              quat_angle, simulate, state_log, window_errors)


def _rot(axis, angle):
    """Quaternion (qw, qx, qy, qz) of a rotation by ``angle`` rad about unit ``axis``."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    angle = np.asarray(angle, float)[..., None]
    return np.concatenate([np.cos(angle / 2), np.sin(angle / 2) * axis], axis=-1)


def _state(p, v, q, w):
    return np.concatenate([p, v, q, w], axis=-1)


# -- the metric --------------------------------------------------------------------------------
def test_window_errors_of_a_known_error_in_each_quantity():
    q_true = _rot([1.0, 2.0, -0.5], 0.7)
    # predicted attitude: the true one turned by 0.3 rad about another axis (body side)
    q_pred = qmul(q_true, _rot([0.0, 1.0, 1.0], 0.3))
    true = _state([1.0, 2.0, 3.0], [0.5, -0.5, 0.0], q_true, [0.1, 0.2, 0.3])[None, None]
    pred = _state([4.0, 6.0, 3.0], [1.5, 1.5, 2.0], -q_pred, [0.1, 0.2, -1.7])[None, None]
    e = window_errors(pred, true)
    assert e["position"][0, 0] == pytest.approx(5.0)      # (3, 4, 0)
    assert e["velocity"][0, 0] == pytest.approx(3.0)      # (1, 2, 2)
    assert e["attitude"][0, 0] == pytest.approx(0.3)      # sign of q does not matter
    assert e["rates"][0, 0] == pytest.approx(2.0)         # (0, 0, -2)


def test_quat_angle_is_the_geodesic_angle_up_to_pi():
    q0 = _rot([0.0, 0.0, 1.0], 0.2)
    for a in (0.0, 0.5, 2.0, 3.0):
        assert quat_angle(q0, qmul(q0, _rot([1.0, 0.0, 0.0], a))) == pytest.approx(a, abs=1e-12)
    # beyond pi the shorter way round is reported
    assert quat_angle(q0, qmul(q0, _rot([1.0, 0.0, 0.0], 4.0))) == pytest.approx(2 * math.pi - 4.0)


def _ramp_log(n=300, dt=0.01):
    """A hand-made flight: position x = t, velocity z = 2t, yaw = 0.5 t, body rate wx = 3t.
    (The states need not be consistent with each other: the metric only compares them.)"""
    t = dt * np.arange(n)
    z = np.zeros(n)
    state = np.column_stack([t, z, z, z, z, 2 * t, _rot([0.0, 0.0, 1.0], 0.5 * t), 3 * t, z, z])
    return StateLog("ramp", t, state, np.full((n, 4), 1000.0), dt)


def test_constant_model_on_ramps_gives_the_hand_computed_mae_and_simerr():
    log, H, dt = _ramp_log(), 50, 0.01
    res = open_loop({"constant": Constant()}, [log], max_horizon=H)
    s = res["constant"]
    assert s.windows == len(log) - H
    slope = {"position": 1.0, "velocity": 2.0, "attitude": 0.5, "rates": 3.0}
    for h in (1, 10, 50):
        for q in QUANTITIES:
            assert s.at(h)[q] == pytest.approx(slope[q] * h * dt, rel=1e-9)
    for q in QUANTITIES:   # Σ_{h=1..50} c·h·dt = c·dt·1275
        assert s.simerr[q] == pytest.approx(slope[q] * dt * H * (H + 1) / 2, rel=1e-9)
    d = res.to_dict()
    assert list(d) == ["constant"]
    assert list(d["constant"]) == ["1", "10", "50", "simerr"]
    assert set(d["constant"]["simerr"]) == set(QUANTITIES)


def test_errors_pool_windows_over_flights():
    a, b = _ramp_log(200), _ramp_log(120)
    res = open_loop({"c": Constant()}, [a, b], max_horizon=10, horizons=(1, 10))
    assert res["c"].windows == (200 - 10) + (120 - 10)
    assert res["c"].at(10)["position"] == pytest.approx(0.1)
    assert list(res.to_dict()["c"]) == ["1", "10", "simerr"]


def test_open_loop_rejects_flights_with_different_steps():
    with pytest.raises(DataError):
        open_loop({"c": Constant()}, [_ramp_log(dt=0.01), _ramp_log(dt=0.02)])


# -- RK4 -----------------------------------------------------------------------------------------
class _Rigid:
    """v̇ = a (constant, world), ω̇ = 0."""

    def __init__(self, a=(0.0, 0.0, -9.81)):
        self.a = np.asarray(a, float)

    def accel(self, state, u):
        return np.broadcast_to(self.a, (state.shape[0], 3)).copy()

    def ang_accel(self, state, u):
        return np.zeros((state.shape[0], 3))


def test_free_fall_is_exact_parabola():
    p0, v0 = np.array([1.0, -2.0, 10.0]), np.array([0.5, 0.0, 3.0])
    x0 = _state(p0, v0, [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0])[None]
    dt, H = 0.01, 80
    out = simulate(_Rigid(), x0, np.zeros((1, H, 4)), dt)
    t = dt * np.arange(1, H + 1)[:, None]
    g = np.array([0.0, 0.0, -9.81])
    np.testing.assert_allclose(out[0, :, 0:3], p0 + v0 * t + 0.5 * g * t ** 2, atol=1e-12)
    np.testing.assert_allclose(out[0, :, 3:6], v0 + g * t, atol=1e-12)


def test_constant_body_rate_rotates_by_the_right_angle_and_keeps_unit_norm():
    q0 = _rot([0.3, -1.0, 0.2], 0.9)
    w = np.array([0.4, -1.2, 2.0])            # body rates, rad/s, |w| = 2.366
    x0 = _state(np.zeros(3), np.zeros(3), q0, w)[None]
    dt, H = 0.01, 100
    out = simulate(_Rigid((0.0, 0.0, 0.0)), x0, np.zeros((1, H, 4)), dt)
    q = out[0, :, 6:10]
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-14)
    t = dt * np.arange(1, H + 1)
    ang = quat_angle(np.broadcast_to(q0, q.shape), q)
    np.testing.assert_allclose(ang, np.linalg.norm(w) * t, atol=1e-9)
    # body-fixed axis: q(t) = q0 ⊗ exp(ω t / 2)
    expected = qmul(q0, _rot(w, np.linalg.norm(w) * t))
    np.testing.assert_allclose(q, expected, atol=1e-9)
    np.testing.assert_allclose(out[0, :, 10:13], np.broadcast_to(w, (H, 3)))


def test_nominal_physics_hovers_level_and_accelerates_along_body_z():
    m = NominalPhysics(thrust_coeff_N_s2=1e-6, mass_kg=0.5, rad_s_per_rpm=1.0)
    u_hover = math.sqrt(9.81 * 0.5 / 1e-6 / 4)
    level = _state(np.zeros(3), np.zeros(3), [1.0, 0.0, 0.0, 0.0], np.zeros(3))[None]
    np.testing.assert_allclose(m.accel(level, np.full((1, 4), u_hover)), 0.0, atol=1e-12)
    # rolled 90° (right side down... body z points to world -y): thrust sideways, gravity down
    rolled = _state(np.zeros(3), np.zeros(3), _rot([1.0, 0.0, 0.0], math.pi / 2), np.zeros(3))[None]
    np.testing.assert_allclose(m.accel(rolled, np.full((1, 4), u_hover)), [[0.0, -9.81, -9.81]], atol=1e-9)
    assert np.all(m.ang_accel(level, np.zeros((1, 4))) == 0.0)


def test_hover_matched_nominal_balances_gravity_at_the_median():
    n = 100
    rpm = np.full((n, 4), 2000.0)
    log = StateLog("h", 0.01 * np.arange(n), np.tile([0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0.0], (n, 1)), rpm, 0.01)
    m = NominalPhysics.hover_matched([log])
    assert m.specific_thrust(rpm[:1])[0] == pytest.approx(9.81)


# -- state_log -----------------------------------------------------------------------------------
def _flight(n=50, drop=()):
    t = 0.01 * np.arange(n)
    q = _rot([0.0, 0.0, 1.0], 0.3 * t)
    q[1::2] *= -1                              # sign flips: same attitudes
    cols = {"x": t, "y": 2 * t, "z": 0 * t + 1, "vx": 0 * t + 1, "vy": 0 * t + 2, "vz": 0 * t,
            "qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3],
            "wx": 0 * t, "wy": 0 * t, "wz": 0 * t + 0.3}
    sig = {k: Signal(k, t, v, "1") for k, v in cols.items() if k not in drop}
    for i in range(1, 5):
        keep = np.ones(n, bool)
        keep[10 + i] = False                   # each motor misses one sample
        sig[f"rpm{i}"] = Signal(f"rpm{i}", t[keep], 1000.0 * i + t[keep], "rpm")
    return Flight(sig)


def test_state_log_resamples_onto_one_grid_with_a_continuous_quaternion():
    log = state_log(_flight())
    assert len(log) == 50 and log.rpm.shape == (50, 4)
    np.testing.assert_allclose(log.rpm[:, 2], 3000.0 + log.t_s)
    q = log.state[:, 6:10]
    assert np.all(np.sum(q[1:] * q[:-1], axis=1) > 0)
    np.testing.assert_allclose(quat_angle(q, _rot([0.0, 0.0, 1.0], 0.3 * log.t_s)), 0.0, atol=1e-7)


def test_state_log_names_the_missing_signal():
    with pytest.raises(DataError, match="wz"):
        state_log(_flight(drop=("wz",)))
