"""droneid.dataset.suitability.assess on the shared real logs (moved from tests/unit/test_fitness.py): the
verdict for the tilt-drag model at Ts = 0.05 s, and the fitness block of ``droneid inspect``."""
from __future__ import annotations

import json

import pytest

from droneid.cli import main
from droneid.dataset.suitability import TILT_DRAG_SIGNALS, assess
from parsers import read_flight

from conftest import real_log

pytestmark = pytest.mark.real_logs

#: real log -> (read_flight options, expected verdict for the tilt-drag model at Ts = 0.05 s,
#: a phrase of the first problem or of a warning)
REAL = {
    "ardupilot/copter33_quad_log171.bin": ({}, True, "slower than the grid"),
    "mocap/crazyflie_nanodrone/square_run1.csv": ({"vehicle": "multirotor"}, True, None),
    "mocap/crazyflie_nanodrone/melon_run1.csv": ({}, True, "the data look like a multirotor"),
    "mavlink/copter357_quad_mission1.tlog": ({}, False, "vx is logged at 0.9 Hz"),   # gap-aware: 526 in 549 s
    "mavlink/copter34_quad_bench_battery.tlog": ({}, False, "no airborne data"),
    "mcap/sportcub_fixedwing_qualisys.mcap": ({"vehicle": "fixed-wing"}, False, "on a fixed-wing log"),
}


@pytest.mark.parametrize("rel", sorted(REAL))
def test_real_log_verdicts(rel):
    opts, ok, phrase = REAL[rel]
    f = read_flight(real_log(rel), **opts)
    a = assess(f, needed_signals=TILT_DRAG_SIGNALS, ts=0.05)
    assert a.ok is ok, (a.problems, a.warnings)
    if phrase:
        assert any(phrase in m for m in a.problems + a.warnings), (a.problems, a.warnings)


def test_sportcub_without_vehicle_is_refused_and_inspect_shows_the_evidence(capsys):
    path = real_log("mcap/sportcub_fixedwing_qualisys.mcap")
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "type:      unknown (not declared by the log; --vehicle)" in out
    assert "fitness for the tilt-drag/rotor-thrust models (Ts = 0.05 s):" in out
    assert "flies like: not a multirotor" in out and "never hovers" in out
    assert "tilt-drag: REFUSED" in out and "pass --vehicle multirotor" in out
    assert main(["inspect", str(path), "--vehicle", "fixed-wing", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["vehicle_type"] == "fixed-wing"
    assert not d["fitness"]["tilt-drag"]["ok"]


#: undeclared logs -> (read_flight options, whether the data look like a multirotor, a phrase)
UNDECLARED = {
    "mcap/sportcub_fixedwing_qualisys.mcap": ({}, False, "never hovers"),
    **{f"mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv#{b}": ({"body": b}, False, "does not follow its acceleration")
       for b in ("device02", "device03", "device05")},
    **{f"mocap/crazyflie_nanodrone/square_run{i}.csv": ({}, True, None) for i in range(1, 6)},
    **{f"mocap/crazyflie_nanodrone/melon_run{i}.csv": ({}, True, None) for i in (1, 4)},
}


@pytest.mark.parametrize("key", sorted(UNDECLARED))
def test_vehicle_from_the_data_of_undeclared_logs(key):
    """Issue 29: the birds (OptiTrack) and the fixed-wing are refused a multirotor prior with the
    evidence and the override; the Crazyflie runs are accepted; --vehicle multirotor overrides."""
    opts, multirotor, phrase = UNDECLARED[key]
    f = read_flight(real_log(key.split("#")[0]), **opts)
    a = assess(f, needed_signals=TILT_DRAG_SIGNALS, ts=0.05)
    ev = a.flights[0].vehicle
    assert (ev.looks == "multirotor") is multirotor, ev
    vehicle_problems = [p for p in a.problems if "do not look like a multirotor" in p]
    if multirotor:
        assert not vehicle_problems, a.problems
    else:
        assert len(vehicle_problems) == 1 and a.problems[0] == vehicle_problems[0]
        assert phrase in vehicle_problems[0] and "pass --vehicle multirotor" in vehicle_problems[0]
        assert not [p for p in assess(f, needed_signals=TILT_DRAG_SIGNALS, ts=0.05, vehicle="multirotor").problems
                    if "multirotor" in p]


@pytest.mark.parametrize("rel", ["ardupilot/copter33_quad_log171.bin", "mavlink/copter357_quad_mission1.tlog",
                                 "px4/x500_sitl_events.ulg", "px4/octo_px4tools_01_07_59.px4log"])
def test_declared_multirotors_fly_like_multirotors(rel):
    f = read_flight(real_log(rel))
    a = assess(f, needed_signals=TILT_DRAG_SIGNALS, ts=0.5)
    assert a.flights[0].vehicle.looks == "multirotor"
    assert not [p for p in a.problems if "vehicle" in p or "multirotor" in p]


def test_mission_tlog_says_its_motor_commands_are_too_slow(capsys):
    """inspect listed motor1..4 (1 Hz) and said "the log has no motor speeds, motor commands or
    thrust" beside them (issue 40 point 3)."""
    assert main(["inspect", str(real_log("mavlink/copter357_quad_mission1.tlog"))]) == 0
    out = capsys.readouterr().out
    assert "motor1 " in out
    line = next(ln for ln in out.splitlines() if "--prior auto chooses" in ln)
    assert "no motor" not in line and "motor commands (motor1..motor4) come at 1.0 Hz only" in line, line
