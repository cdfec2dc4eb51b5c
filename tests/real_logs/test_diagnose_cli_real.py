"""``droneid diagnose`` end to end on the shared real logs (moved from
tests/integration/test_diagnose_cli.py): the Crazyflie square -> melon pair and the ArduCopter log,
with the prior ``--prior auto`` picks from the logged rotor signals."""
from __future__ import annotations

import json

import pytest

from droneid.cli import main

from conftest import real_log

pytestmark = pytest.mark.real_logs


@pytest.mark.slow
def test_cli_on_crazyflie_square_to_melon(tmp_path, capsys):
    train = real_log("mocap/crazyflie_nanodrone/square_run1.csv")
    test = real_log("mocap/crazyflie_nanodrone/melon_run1.csv")
    rc = main(["-q", "diagnose", str(train), "--test", str(test), "--generations", "0", "--json"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    # --prior auto: the Crazyflie logs motor speeds, so rotor-thrust with v̇z, as identify does
    assert d["prior"].startswith("rotor-thrust (source=rpm, motors=4)")
    assert set(d["targets"]) == {"vx_dot", "vy_dot", "vz_dot"}
    assert "thrust_variation" in d["not_applicable"]
    for v in d["targets"].values():
        assert v["rmse_before"]["test"] is not None


@pytest.mark.slow
def test_cli_on_the_arducopter_log(tmp_path, capsys):
    log = real_log("ardupilot/copter33_quad_log171.bin")
    rc = main(["-q", "diagnose", str(log), "--generations", "0", "--json",
               "--report", str(tmp_path)])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    # --prior auto picks rotor-thrust from the logged motor outputs, which models v̇z too
    assert d["prior"].startswith("rotor-thrust")
    assert set(d["targets"]) == {"vx_dot", "vy_dot", "vz_dot"} and (tmp_path / "diagnosis.html").is_file()
    for v in d["targets"].values():
        assert v["rmse_after"]["train"] <= v["rmse_before"]["train"]
        assert v["n_train"] > 1000          # the crash at the end is trimmed, the flight is kept
