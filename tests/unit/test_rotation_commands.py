"""The rotational stage of a command-driven vehicle (issue 36 item 5; droneid.rotation.commands):
simulated vehicles that log motor commands and battery voltage, their rotor speeds removed, reach
the rotational ladder through the identified motor model, and what it keeps reads the commands.

Planted truth: the simulator's rotors are in the quad_x layout; the roll and pitch torque sign
patterns identified from the commands' normalised thrusts must be that layout's."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from droneid.errors import DataError
from droneid.rotation.commands import CommandSpeeds
from droneid.rotation.model import SPEED_UNIT, RotationModel, identify_layout
from droneid.rotation.stage import RotationResult, choose_rotation
from droneid.simulation.motor_model import MotorModel
from droneid.simulation.openloop import flight_state_logs
from priors.torque import get_layout

EXPO, LAG = 0.5, 0.04


def _flights(n: int = 2, duration_s: float = 14.0):
    from droneid.simulation.simulator import simulate
    return [simulate(path=p, duration_s=duration_s, seed=s, thrust_expo=EXPO, motor_tau_s=LAG,
                     effects={"thrust_variation": {"amp_m": 0.5, "period_s": 3.0 + s}}
                     ).flight.without("rpm1", "rpm2", "rpm3", "rpm4")
            for s, p in enumerate(("random", "lissajous", "eight")[:n])]


@pytest.fixture(scope="module")
def two_flights():
    return _flights()


def _speeds() -> CommandSpeeds:
    return CommandSpeeds(MotorModel(EXPO, lag_s=LAG), 4)


@pytest.mark.slow
def test_the_commands_thrust_differences_show_the_layouts_roll_and_pitch_signs(two_flights):
    logs = [_speeds().speed_log(log) for log in flight_state_logs(two_flights, signals=_speeds().signals())]
    assert all(0.3 < float(np.median(log.rpm)) < 1.0 for log in logs)     # normalised speeds, not rpm
    signs, _ = identify_layout(logs, rad_s_per_rpm=SPEED_UNIT)
    np.testing.assert_array_equal(signs[:2], np.sign(get_layout("quad_x").patterns())[:2])


@pytest.mark.slow
def test_two_command_flights_reach_the_rotational_ladder(two_flights):
    """No rotor speed logged: the stage runs on the commands' speeds, says so in its units, and any
    model it keeps reads the commands (no rotor speed) and answers them with the layout's sign."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rot = choose_rotation(two_flights, frame="quad_x", commands=_speeds())
    assert rot.from_commands and rot.rad_s_per_rpm == SPEED_UNIT
    assert "fraction of full thrust" in rot.speed_note and "not rad/s" in rot.speed_note
    assert [a.target for a in rot.axes] == ["wx_dot", "wy_dot", "wz_dot"]
    assert all(math.isfinite(a.validation_held) and a.validation_held > 0 for a in rot.axes)
    for k, a in enumerate(rot.axes):
        if a.rung in ("held", "damping"):
            assert "does not respond to the motors" in a.verdict
        if a.rung == "torque":
            assert rot.model.coef[k][0] > 0          # the pattern's scale: the layout's sign
    if rot.model is not None:
        assert rot.model.commands == _speeds()
        back = RotationResult.from_dict(rot.to_dict())
        assert back.from_commands and back.model.commands == _speeds()


def test_the_command_path_reads_every_log_the_same_way():
    """A command-driven rotational model takes its inputs from the commands of any state log (the
    test flight's, predict's), never from logged rotor speeds: a log whose rotor speeds are
    garbage gives the same inputs."""
    from dataclasses import replace
    layout = get_layout("quad_x")
    rot = RotationModel(layout, ("damping",), (np.array([30.0, 1.0]),) * 3, np.zeros(3),
                        rad_s_per_rpm=SPEED_UNIT, lowpass_tau_s=0.05, commands=_speeds())
    log = flight_state_logs(_flights(1, 6.0), signals=_speeds().signals())[0]
    garbage = replace(log, rpm=np.full((len(log), 4), 1e6))
    np.testing.assert_array_equal(rot.inputs(log), rot.inputs(garbage))
    assert rot.signals() == ("motor1", "motor2", "motor3", "motor4")
    assert RotationModel.from_dict(rot.to_dict()).commands == rot.commands


def test_one_command_flight_cannot_choose():
    with pytest.raises(DataError, match="at least two training flights"):
        choose_rotation(_flights(1, 6.0), frame="quad_x", commands=_speeds())


def test_a_collective_throttle_gives_no_per_rotor_speeds():
    cfg = {"prior_params": {"source": "throttle", "expo": 0.5}, "thrust_curve": {"lag_s": 0.0}}
    assert CommandSpeeds.from_record(cfg) is None
    cfg = {"prior_params": {"source": "motor", "motors": 4, "expo": 0.5, "v_ref": 12.6},
           "thrust_curve": {"lag_s": 0.0}, "delays_s": {"motor1": 0.03}}
    speeds = CommandSpeeds.from_record(cfg)
    assert speeds.offset_s == 0.03 and speeds.offset_steps(0.01) == 3
    assert speeds.signals() == ("motor1", "motor2", "motor3", "motor4", "battery_voltage")
