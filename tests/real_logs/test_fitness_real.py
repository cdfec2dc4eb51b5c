"""droneid.fitness.assess on the shared real logs (moved from tests/unit/test_fitness.py): the
verdict for the tilt-drag model at Ts = 0.05 s, and the fitness block of ``droneid inspect``."""
from __future__ import annotations

import json

import pytest

from droneid.cli import main
from droneid.fitness import TILT_DRAG_SIGNALS, assess
from parsers import read_flight

from conftest import real_log

pytestmark = pytest.mark.real_logs

#: real log -> (read_flight options, expected verdict for the tilt-drag model at Ts = 0.05 s,
#: a phrase of the first problem or of a warning)
REAL = {
    "ardupilot/copter33_quad_log171.bin": ({}, True, "slower than the grid"),
    "mocap/crazyflie_nanodrone/square_run1.csv": ({"vehicle": "multirotor"}, True, None),
    "mocap/crazyflie_nanodrone/melon_run1.csv": ({}, True, "vehicle type unknown"),
    "mavlink/copter357_quad_mission1.tlog": ({}, False, "logged at 1.0 Hz"),
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


def test_sportcub_without_vehicle_is_a_warning_and_inspect_shows_the_block(capsys):
    path = real_log("mcap/sportcub_fixedwing_qualisys.mcap")
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "type:      unknown (not declared by the log; --vehicle)" in out
    assert "fitness for the tilt-drag/rotor-thrust models (Ts = 0.05 s):" in out
    assert "vehicle type unknown" in out
    assert main(["inspect", str(path), "--vehicle", "fixed-wing", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["vehicle_type"] == "fixed-wing"
    assert not d["fitness"]["tilt-drag"]["ok"]
