"""``droneid diagnose`` end to end on the shipped sample logs (on the real logs:
tests/real_logs/test_diagnose_cli_real.py)."""
from __future__ import annotations

import json

import pytest

from droneid.cli import main

from conftest import SAMPLE_LOGS


@pytest.mark.slow
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


def test_a_late_motor_stream_is_not_diagnosed_as_an_attitude_delay(capsys):
    """rotor_climb_eight logs its motor speeds 40 ms late (truth: rpm_delay_s 0.04) and has no
    attitude delay: the diagnosis (which searches no input offset; identify does) must not add an
    attitude delay in its place (a feature that left dT/dt out of dG/dt did: 'lags by 31 ms')."""
    truth = json.loads((SAMPLE_LOGS / "rotor_climb_eight.truth.json").read_text())
    assert truth["params"]["rpm_delay_s"] > 0
    rc = main(["-q", "diagnose", str(SAMPLE_LOGS / "rotor_climb_eight.tlog"), "--generations", "0",
               "--json"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 0 and "attitude_delay" not in d["effects_added"]
