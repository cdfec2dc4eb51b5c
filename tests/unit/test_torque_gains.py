"""The vehicle's torque gains (droneid.rotation.gains, issue 37.4) against planted truth: a rigid
body driven by its rotors through the layout, a rotor drag moment and a decay, a balance point of
its own per flight, gyro noise on the logged rates. The gain of each axis must come back inside
its interval, be called constant when every flight has it, NOT constant when one flight's differs,
and a test flight with another gain must be said not to hold it; a flight whose motor stream is
stamped early is read at its own alignment (a flight condition)."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.rotation.gains import TorqueGains, check_gains, torque_gains
from droneid.rotation.model import RotationModel, TranslationModel
from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM, IdentifiedVehicle, StateLog, simulate
from priors.torque import get_layout
from test_rotation import _smooth_noise

DT = 0.01
LAYOUT = get_layout("crazyflie_x")
TERMS = ("damping", "rotor_drag")
#: planted per axis: [pattern, damping, rotor drag] (roll, pitch), [pattern, damping] (yaw)
COEF = (np.array([6.0, 3.0, 2.0]), np.array([5.0, 3.0, 1.5]), np.array([1.5, 3.0]))
CANDIDATE = {"terms": TERMS}


def _flight(seed: int, coef=COEF, n: int = 1500, noise: float = 0.02, name: str | None = None,
            early_steps: int = 0) -> StateLog:
    """A planted flight; ``early_steps``: its motor stream is stamped that many steps early (a
    clock offset: the rotor speed logged at t turned at t + early_steps·dt)."""
    rng = np.random.default_rng(seed)
    rpm = 95000.0 + rng.normal(0, 300, 4) + _smooth_noise(rng, n, 4, 2500.0)
    shell = RotationModel(LAYOUT, TERMS, coef, np.zeros(3))
    s_mean = shell.conditioned(rpm, DT)[0].mean(axis=0)
    trim = -np.array([coef[k][0] * (LAYOUT.patterns()[k] @ s_mean) for k in range(3)])
    truth = IdentifiedVehicle(TranslationModel(k_thrust=0.83, drag=np.array([0.3, 0.2, 0.1])),
                              RotationModel(LAYOUT, TERMS, coef, trim))
    dummy = StateLog(name or f"flight{seed}", DT * np.arange(n), np.zeros((n, 13)), rpm, DT)
    x0 = np.array([0, 0, 100.0, 0.5, -0.3, 0, 1, 0, 0, 0, 0.2, -0.1, 0.0])
    states = np.vstack([x0, simulate(truth, x0[None], truth.inputs(dummy)[None, :-1], DT)[0]])
    states[:, 10:13] += noise * rng.standard_normal((n, 3))
    if early_steps:
        rpm = np.concatenate([rpm[early_steps:], np.repeat(rpm[-1:], early_steps, axis=0)])
    return StateLog(dummy.name, dummy.t_s, states, rpm, DT)


def _gains(logs) -> TorqueGains:
    return torque_gains(logs, LAYOUT, CANDIDATE, rad_s_per_rpm=CRAZYFLIE_RAD_S_PER_ERPM, unit="rad/s² per unit", n_boot=100)


@pytest.fixture(scope="module")
def same():
    return [_flight(s) for s in (21, 22, 23)]


@pytest.mark.slow   # simulated flights, about 5 s
def test_planted_gains_are_recovered_inside_their_intervals_and_constant(same):
    g = _gains(same)
    for k, axis in enumerate(("roll", "pitch", "yaw")):
        v, lo, hi = g.gains[axis]
        assert lo <= COEF[k][0] <= hi, (axis, g.gains[axis])
        assert v == pytest.approx(COEF[k][0], rel=0.05), axis
        assert g.constancy[axis].constant is True, (axis, g.constancy[axis])
        assert set(g.constancy[axis].per_unit) == {"flight21", "flight22", "flight23"}
    assert TorqueGains.from_dict(g.to_dict()).gains == g.gains


@pytest.mark.slow
def test_a_flight_whose_gain_differs_is_flagged_in_training_and_as_a_test_flight(same):
    other = (COEF[0] * np.array([1.6, 1, 1]), COEF[1], COEF[2])
    g = _gains([*same, _flight(24, other)])
    assert g.constancy["roll"].constant is False
    assert g.constancy["yaw"].constant is True
    tested = check_gains(_gains(same), [_flight(25, other, name="odd"), _flight(26, name="alike")]).tested
    assert tested["odd"]["roll"][4] is False and tested["odd"]["roll"][0] == pytest.approx(9.6, rel=0.05)
    assert all(v[4] is True for v in tested["alike"].values()), tested["alike"]
    assert tested["odd"]["pitch"][4] is True


@pytest.mark.slow
def test_each_flight_is_read_at_its_own_alignment_of_the_motor_stream(same):
    g = _gains([*same[:2], _flight(27, early_steps=3, name="late_clock")])
    assert g.conditions["late_clock"][0] == pytest.approx(0.03)
    assert g.conditions["flight21"][0] == pytest.approx(0.0)
    for k, axis in enumerate(("roll", "pitch", "yaw")):
        assert g.constancy[axis].per_unit["late_clock"][0] == pytest.approx(COEF[k][0], rel=0.05), axis
        assert g.constancy[axis].constant is True, axis
