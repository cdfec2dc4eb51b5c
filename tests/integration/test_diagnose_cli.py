"""``droneid diagnose`` end to end on the shipped sample logs (and the real logs when present)."""
from __future__ import annotations

import json

import pytest

from droneid.cli import main

from conftest import SAMPLE_LOGS, real_log


def test_cli_finds_wind_then_quadratic_drag_in_the_sample_log(tmp_path, capsys):
    log = SAMPLE_LOGS / "wind_quadratic_eight.tlog"
    rc = main(["-q", "diagnose", str(log), "--generations", "0", "--json",
               "--report", str(tmp_path / "rep")])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    assert d["effects_added"] == ["wind", "quadratic_drag"]     # planted: wind (1.5, -1), c = 0.15
    fin = {f["effect"]: f["physical_values"] for f in d["final_effects"]}
    assert abs(fin["quadratic_drag"]["c_D_over_m_per_m"] - 0.15) < 0.03
    assert abs(fin["wind"]["w_x_m_s"] - 1.5) < 0.3 and abs(fin["wind"]["w_y_m_s"] + 1.0) < 0.2
    for name in ("diagnosis.json", "diagnosis.md", "diagnosis.html", "residual_time.png"):
        assert (tmp_path / "rep" / name).is_file()
    on_disk = json.loads((tmp_path / "rep" / "diagnosis.json").read_text())
    assert on_disk["effects_added"] == d["effects_added"]


def test_cli_summary_and_control_pair(capsys):
    rc = main(["-q", "diagnose", str(SAMPLE_LOGS / "paper_train_eight.mcap"), "--test",
               str(SAMPLE_LOGS / "paper_test_square.mcap"), "--generations", "0"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "effects added: none" in out and "no further effect is detectable" in out


def test_cli_errors_are_one_line(tmp_path, capsys):
    rc = main(["diagnose", str(SAMPLE_LOGS / "paper_train_eight.tlog"), "--only", "wnd",
               "--generations", "0"])
    err = capsys.readouterr().err
    assert rc == 2 and "did you mean 'wind'" in err and len(err.strip().splitlines()) == 1
    rc = main(["diagnose", str(tmp_path / "missing.csv")])
    assert rc == 2


@pytest.mark.slow
@pytest.mark.real_logs
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
@pytest.mark.real_logs
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
