"""Diagnosis reports: terminal summary, diagnosis.json, Markdown/HTML with plots."""
from __future__ import annotations

import json

import diag_synth as S
from droneid.diagnose import DiagnoseConfig, diagnose_datasets
from droneid.report.diagnose import write
from droneid.report.diagnose import text as render_text


def _result(effect="wind", params=None):
    params = params or {"wx": 2.0, "wy": -1.5}
    return diagnose_datasets(S.make(effect, params, seed=1, duration_s=40),
                             S.make(effect, params, seed=2, phase=1.0, duration_s=40),
                             prior=S.TiltDragStub(), config=DiagnoseConfig(generations=0))


def test_summary_names_effect_values_and_errors():
    txt = render_text(_result())
    assert "1. wind: wind ≈ (2, -1.5) m/s" in txt
    assert "train" in txt and "test" in txt and "no further effect is detectable" in txt


def test_write_report(tmp_path):
    r = _result("attitude_bias", {"pitch_deg": -2.0})
    paths = write(r, tmp_path / "rep")
    d = json.loads((tmp_path / "rep" / "diagnosis.json").read_text())
    assert d["effects_added"] == ["attitude_bias"]
    assert d["targets"]["vx_dot"]["steps"][0]["effect"] == "attitude_bias"
    assert "pitch bias" in (tmp_path / "rep" / "diagnosis.md").read_text()
    html = (tmp_path / "rep" / "diagnosis.html").read_text()
    assert "data:image/png;base64," in html
    assert {"residual_time", "step1_attitude_bias", "rmse_steps"} <= set(paths)


def test_summary_of_control_lists_untestable(tmp_path):
    r = diagnose_datasets(S.make(None, seed=0, drop=("battery_voltage",), duration_s=40), None,
                          prior=S.TiltDragStub(), config=DiagnoseConfig(generations=0))
    txt = render_text(r)
    assert "effects added: none" in txt and "battery_sag: needs battery_voltage" in txt
    write(r, tmp_path)
    assert (tmp_path / "diagnosis.html").is_file()


def test_residual_plot_is_not_bridged_across_ground_time_or_between_flights():
    from types import SimpleNamespace

    import numpy as np

    from droneid.report.diagnose import fig_residual_time
    t = np.r_[np.arange(0, 10, 0.05), np.arange(46, 50, 0.05), np.arange(0, 5, 0.05)]  # 36 s on the ground
    fl = np.r_[np.zeros(200 + 80, int), np.ones(100, int)]
    res = np.sin(t)
    r = SimpleNamespace(series={"vz_dot": {"t": t, "flight": fl, "residual_before": res,
                                           "residual_after": 0.5 * res}}, steps=[{"effect": "x"}])
    fig = fig_residual_time(r)
    ax = fig.axes[0]
    assert ax.get_ylabel() == "vz_dot residual (m/s²)" and ax.get_xlabel() == "time (s)"
    for ln in ax.get_lines():
        x, y = np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float)
        gaps = np.flatnonzero(np.isnan(y))
        assert gaps.tolist() == [200, 281]  # after the ground time, and where flight 2 starts
        assert x[199] < 10 <= 46 <= x[201]


def test_axis_labels_of_explaining_signals_carry_units():
    from droneid.report.diagnose import _with_unit
    assert _with_unit("t") == "t (s)" and _with_unit("vz") == "vz (m/s)" and _with_unit("yaw") == "yaw (rad)"


def test_a_saved_diagnosis_reads_back_and_renders_the_same_summary(tmp_path):
    import pytest

    from droneid.diagnose import DiagnosisResult
    from droneid.errors import DataError
    r = _result()
    d = json.loads(json.dumps(r.to_dict()))
    back = DiagnosisResult.from_dict(d)
    assert back.to_dict() == d and back.series == {}
    assert render_text(d) == render_text(r)          # the JSON document renders as the object does
    paths = write(d, tmp_path / "rep")                # no series: a report without time-series figures
    assert json.loads((tmp_path / "rep" / "diagnosis.json").read_text()) == d and paths
    with pytest.raises(DataError, match="not a diagnosis result"):
        DiagnosisResult.from_dict({"targets": {}})


def test_open_ended_fallback_says_a_residual_remains_or_one_line():
    from droneid.report.diagnose import _fallback_lines
    ev = {"text": "open-ended term for vx_dot: CV RMSE 1 -> 0.8 (-20.0 %), ...: accepted",
          "test_rel_improvement": None}
    passed = {"vx_dot": {"ran": True, "passed": True, "equation": "0.3*vx*rpm1", "evidence": ev},
              "vy_dot": {"ran": True, "passed": False, "equation": "0.01*vy", "evidence": ev}}
    lines = _fallback_lines(passed)
    assert "SIGNIFICANT RESIDUAL REMAINS" in lines[0] and "none was added in its place" in lines[0]
    assert any("0.3*vx*rpm1" in x for x in lines) and not any("0.01*vy" in x for x in lines)
    assert any("accepted" in x for x in lines)
    quiet = {t: {**o, "passed": False} for t, o in passed.items()}
    assert len(_fallback_lines(quiet)) == 1 and "no significant residual" in _fallback_lines(quiet)[0]
