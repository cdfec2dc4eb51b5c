"""Diagnosis reports: terminal summary, diagnosis.json, Markdown/HTML with plots."""
from __future__ import annotations

import json

import diag_synth as S
from droneid.diagnose import DiagnoseConfig, diagnose_datasets
from droneid.diagnose_report import summary_text, write_report


def _result(effect="wind", params=None):
    params = params or {"wx": 2.0, "wy": -1.5}
    return diagnose_datasets(S.make(effect, params, seed=1, duration_s=40),
                             S.make(effect, params, seed=2, phase=1.0, duration_s=40),
                             prior=S.TiltDragStub(), config=DiagnoseConfig(sngp_generations=0))


def test_summary_names_effect_values_and_errors():
    txt = summary_text(_result())
    assert "1. wind: wind ≈ (2, -1.5) m/s" in txt
    assert "train" in txt and "test" in txt and "no further effect is detectable" in txt


def test_write_report(tmp_path):
    r = _result("attitude_bias", {"pitch_deg": -2.0})
    paths = write_report(r, tmp_path / "rep")
    d = json.loads((tmp_path / "rep" / "diagnosis.json").read_text())
    assert d["effects_added"] == ["attitude_bias"]
    assert d["targets"]["vx_dot"]["steps"][0]["effect"] == "attitude_bias"
    assert "pitch bias" in (tmp_path / "rep" / "diagnosis.md").read_text()
    html = (tmp_path / "rep" / "diagnosis.html").read_text()
    assert "data:image/png;base64," in html
    assert {"residual_time", "step1_attitude_bias", "rmse_steps"} <= set(paths)


def test_summary_of_control_lists_untestable(tmp_path):
    r = diagnose_datasets(S.make(None, seed=0, drop=("battery_voltage",), duration_s=40), None,
                          prior=S.TiltDragStub(), config=DiagnoseConfig(sngp_generations=0))
    txt = summary_text(r)
    assert "effects added: none" in txt and "battery_sag: needs battery_voltage" in txt
    write_report(r, tmp_path)
    assert (tmp_path / "diagnosis.html").is_file()
