"""Refusals that hid or misdirected (issue 40 point 3): every problem is shown, every option a
refusal names exists on the command that meets it, the prior choice says when motor signals
exist but are too slow, and a fixed-wing log is told plainly that droneid has no model of it."""
from __future__ import annotations

import argparse
import re
from dataclasses import replace

import numpy as np
import pytest

from droneid.cli import build_parser
from droneid.errors import DataError
from droneid.logs.flight import Flight, Provenance, Signal
from droneid.dataset.suitability import TILT_DRAG_SIGNALS, assess, check_prior_data, fitness_by_prior
from priors.registry import get_prior


def _flight(duration=30.0, rate=100.0, armed=True, fmt="csv", vehicle="multirotor", slow_motors=None) -> Flight:
    t = np.arange(0, duration, 1 / rate)
    w = 2 * np.pi / 10
    sig = [Signal("roll", t, 0.17 * np.sin(w * t), "rad"), Signal("pitch", t, 0.09 * np.cos(w * t), "rad"),
           Signal("yaw", t, 1.5 * t / duration, "rad"), Signal("vx", t, 1.5 + 1.5 * np.sin(w * t), "m/s"),
           Signal("vy", t, 0 * t, "m/s"), Signal("vz", t, 0 * t, "m/s"), Signal("z", t, 2 + 0 * t, "m")]
    if slow_motors:
        tm = np.arange(0, duration, 1 / slow_motors)
        sig += [Signal(f"motor{i}", tm, 0.5 + 0 * tm, "1") for i in range(1, 5)]
    seg = {"armed": ((0.0, duration),) if armed else (), "in_flight": ((0.0, duration),) if armed else ()}
    prov = Provenance(files=(f"planted.{fmt}",), format=fmt, vehicle_type=vehicle, vehicle_declared="test")
    return Flight({s.name: s for s in sig}, prov, segments=seg)


def _options(command: str) -> set[str]:
    """Every option string the CLI's ``command`` accepts (its own and the global ones)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {s for a in sub.choices[command]._actions for s in a.option_strings}


def _named_options(text: str) -> set[str]:
    return set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", text))


def test_a_refusal_shows_every_problem_not_a_count():
    """Was: "... (and 2 more problem(s))" with the others nowhere."""
    f = _flight(armed=False).without("yaw")
    slow = _flight(rate=1.0)
    fit = assess([f, slow], needed_signals=TILT_DRAG_SIGNALS, ts=0.05)
    assert len(fit.problems) >= 3, fit.problems
    with pytest.raises(DataError) as err:
        fit.raise_if_refused("the training data cannot identify the tilt-drag model: ")
    msg = str(err.value)
    assert "more problem" not in msg
    for p in fit.problems:
        assert p in msg
    assert "\n" not in msg and msg.startswith(f"the training data cannot identify the tilt-drag model: "
                                              f"{len(fit.problems)} problems: (1) ")


@pytest.mark.parametrize("command", ["identify", "diagnose"])
def test_the_no_airborne_refusal_names_only_options_of_the_command_run(command):
    """Was: "choose the part to use (droneid dataset --in-flight all / --window)", options that
    identify and diagnose do not have."""
    with pytest.raises(DataError, match="no airborne data") as err:
        check_prior_data([_flight(armed=False)], get_prior("tilt-drag"), ("vx_dot", "vy_dot"), 0.05)
    named = _named_options(str(err.value))
    assert named <= _options(command), named - _options(command)


def test_predict_names_a_fix_it_has_for_a_missing_signal():
    """Was: "map a column to it (--column yaw=COLUMN) or choose other inputs": predict cannot
    choose inputs, the model it applies reads yaw."""
    from droneid.use.predict import _fitness
    models = {"vx_dot": {"inputs": ["vx", "roll", "pitch", "yaw"]}}
    with pytest.raises(DataError, match="signal 'yaw' is missing") as err:
        _fitness(models, [_flight().without("yaw")], 0.05)
    msg = str(err.value)
    assert "choose other inputs" not in msg and "use a log that has it" in msg
    assert _named_options(msg) <= _options("predict")
    ulog = _flight().without("yaw")
    ulog = replace(ulog, provenance=replace(ulog.provenance, format="ulog"))
    with pytest.raises(DataError) as err:
        _fitness(models, [ulog], 0.05)
    assert "choose other inputs" not in str(err.value) and "use a log that has it" in str(err.value)


def test_identify_names_a_prior_or_target_for_a_missing_signal():
    a = assess(_flight().without("yaw"), needed_signals=TILT_DRAG_SIGNALS, ts=0.05)
    named = _named_options(a.problems[0])
    assert {"--column", "--prior", "--target"} <= named and named <= _options("identify")
    assert "choose other inputs" not in a.problems[0]


def test_slow_motor_commands_are_named_not_denied():
    """Was: "--prior auto chooses: tilt-drag (the log has no motor speeds, motor commands or
    thrust)" beside a table listing motor1..4 (at 1 Hz)."""
    auto = fitness_by_prior([_flight(slow_motors=1.0)], ts=0.05)["auto"]
    assert auto["prior"] == "tilt-drag"
    assert "no motor" not in auto["reason"], auto["reason"]
    assert "motor commands (motor1..motor4)" in auto["reason"] and "1.0 Hz" in auto["reason"]
    fast = fitness_by_prior([_flight(slow_motors=50.0)], ts=0.05)["auto"]
    assert fast["prior"] == "rotor-thrust"
    assert fitness_by_prior([_flight()], ts=0.05)["auto"]["reason"] == \
        "the log has no motor speeds, motor commands or thrust"


def test_a_fixed_wing_is_told_droneid_has_no_fixed_wing_model():
    """Was only: "pass --vehicle multirotor to override"."""
    a = assess(_flight(vehicle="fixed-wing"), needed_signals=TILT_DRAG_SIGNALS, ts=0.05)
    assert "droneid has no built-in fixed-wing model" in a.problems[0]
    assert "--prior FILE.toml:NAME" in a.problems[0] and "pass --vehicle multirotor" in a.problems[0]
    rover = assess(_flight(vehicle="rover"), needed_signals=TILT_DRAG_SIGNALS, ts=0.05)
    assert "--prior unicycle" in rover.problems[0]


def test_the_ground_effect_names_where_the_ground_height_can_be_set():
    """Was: "the ground is not at a known height (set ground_z_m)", which no command line option
    sets (seen on the px4log octocopter, whose local z goes 1 m below its origin)."""
    from types import SimpleNamespace
    from priors.effect_catalogue import ground_effect
    why = ground_effect._preconditions(SimpleNamespace(columns={"z": np.linspace(-1, 5, 200)}, options={}))
    assert "set ground_z_m" not in why and "DiagnoseConfig(ground_z_m=...)" in why
    assert _named_options(why) <= _options("diagnose")
