"""The yaw spin-up rung (droneid.rotation.spinup, issue 37.4): the rate decay plus the rotors'
reaction to their own acceleration, its alignment, motor lag and gain chosen on training flights,
recovered from flights with a planted reaction; none found where none is planted; the rung is on
yaw's ladder only and answers the motors in the per-axis model."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM, StateLog
from droneid.rotation.model import SPEED_UNIT
from droneid.rotation.choice import per_axis_model
from droneid.rotation.ladder import _ladder_steps
from droneid.rotation.spinup import Spinup, fit_spinup, spinup_folds, spinup_interval
from priors.torque import get_layout

DT = 0.01
LAYOUT = get_layout("crazyflie_x")
C_YAW = 2.0


def _spun_flight(seed: int, gain: float, delay: int = 2, n: int = 4000, name: str = "spin") -> StateLog:
    """Yaw rate driven by a planted spin-up reaction ``ω̇z = −c ω_z + gain (P ṡpin)_z`` of the rotor
    speeds ``delay`` steps earlier, plus random torque kicks (so the decay alone has work to do);
    the motors' yaw differences step at random times, the vehicle airborne."""
    rng = np.random.default_rng(seed)
    erpm = np.full((n, 4), 90000.0)
    level = np.zeros(4)
    for i in range(n):
        if rng.random() < 0.02:
            level = rng.normal(0.0, 6000.0) * LAYOUT.patterns()[2]
        erpm[i] = 90000.0 + level
    om = erpm * (CRAZYFLIE_RAD_S_PER_ERPM / SPEED_UNIT)
    rate = np.zeros_like(om)
    rate[1:] = np.diff(om, axis=0) / DT
    drive = np.concatenate([np.zeros(delay), (rate @ LAYOUT.patterns()[2])[:n - delay]])
    w = np.zeros(n)
    for i in range(1, n):
        kick = rng.normal(0.0, 1.0) if rng.random() < 0.01 else 0.0
        w[i] = w[i - 1] * np.exp(-C_YAW * DT) + DT * gain * drive[i - 1] + kick
    state = np.zeros((n, 13))
    state[:, 2] = 1.0
    state[:, 6] = 1.0
    state[:, 12] = w
    return StateLog(name, DT * np.arange(n), state, erpm, DT)


def test_a_planted_spinup_reaction_is_recovered_with_its_alignment():
    logs = [_spun_flight(1, 0.05, name="a"), _spun_flight(2, 0.05, name="b")]
    got = fit_spinup(logs, LAYOUT, C_YAW, rad_s_per_rpm=CRAZYFLIE_RAD_S_PER_ERPM, lowpass=(None,))
    assert (got.gain, got.delay_steps, got.damping_per_s) == (0.05, 2, C_YAW)
    lo, hi = spinup_interval(logs, LAYOUT, got, C_YAW, rad_s_per_rpm=CRAZYFLIE_RAD_S_PER_ERPM, n_boot=40)
    assert lo <= 0.05 <= hi and lo > 0.0


def test_no_reaction_is_found_where_none_is_planted():
    logs = [_spun_flight(3, 0.0, name="a"), _spun_flight(4, 0.0, name="b")]
    got = fit_spinup(logs, LAYOUT, C_YAW, rad_s_per_rpm=CRAZYFLIE_RAD_S_PER_ERPM)
    assert got.gain == 0.0


def test_the_folds_choose_on_the_other_flights_only():
    decays = {n: np.array([1.0, 1.0, C_YAW]) for n in "abc"}
    kw = {"rad_s_per_rpm": CRAZYFLIE_RAD_S_PER_ERPM}
    planted_elsewhere = [_spun_flight(5, 0.05, name="a"), _spun_flight(6, 0.05, name="b"), _spun_flight(7, 0.0, name="c")]
    assert spinup_folds(planted_elsewhere, LAYOUT, decays, **kw)["c"].gain == 0.05
    planted_here = [_spun_flight(5, 0.0, name="a"), _spun_flight(6, 0.0, name="b"), _spun_flight(7, 0.05, name="c")]
    assert spinup_folds(planted_here, LAYOUT, decays, **kw)["c"].gain == 0.0


def test_the_spinup_rung_is_on_yaws_ladder_only_and_answers_the_motors():
    rungs = ("held", "damping", "spinup", "torque")
    assert [r for r, _ in _ladder_steps(rungs, 0)] == ["damping", "torque"]
    assert [r for r, _ in _ladder_steps(rungs, 2)] == ["damping", "spinup", "torque"]
    spin = Spinup(3, 0.03, 0.05, 1.0)
    m = per_axis_model(("damping", "damping", "spinup"), [4.0, 2.0, 1.0], None, LAYOUT, CRAZYFLIE_RAD_S_PER_ERPM,
                       spinup=spin)
    assert (m.delay_steps, m.lowpass_tau_s) == (3, 0.03)
    assert dict(zip(m.columns(2), m.coef[2])) == {"pattern": 0.0, "damping": 1.0, "spinup": 0.05}
    assert m.unsteerable_axes() == ("roll", "pitch")
    # spinning the clockwise rotors (spin +1) up turns the body counter-clockwise (+z, FLU)
    u = np.zeros((1, 8))
    u[0, 4:] = [-1.0, 1.0, -1.0, 1.0]
    assert m.ang_accel_from(np.zeros((1, 3)), u[:, :4], u[:, 4:])[0, 2] == pytest.approx(0.05 * 4)
    with pytest.raises(Exception, match="yaw only"):
        per_axis_model(("spinup", "damping", "damping"), [4.0, 2.0, 1.0], None, LAYOUT, 1.0, spinup=spin)
