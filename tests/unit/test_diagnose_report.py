"""Diagnosis reports: terminal summary, diagnosis.json, Markdown/HTML with plots."""
from __future__ import annotations

import json

import diag_synth as S
from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose_datasets
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

    from droneid.diagnosis.diagnose import DiagnosisResult
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


# -- one output, one story (issue 29 item 6): built by hand, so each case is certain -------------
def _ev(what, passed, test=None, p=2e-05, thr=0.00067):
    verdict = "accepted" if passed else f"rejected (block test p = {p:.2g} ≥ {thr:.2g})"
    ev = {"cv_rmse_before": 1.0, "cv_rmse_after": 0.8, "rel_improvement": 0.2, "p_value": p,
          "p_threshold": thr, "statistic": 5.0, "n_blocks": 16, "blocks_improved": "15/16",
          "passed": passed, "reasons": [] if passed else ["block test p"], "indistinguishable_from": [],
          "text": f"{what}: CV RMSE 1 -> 0.8 (-20.0 %), t = 5.00 over 16 blocks, sign-flip p = {p:.2g} "
                  f"{'<' if passed else '≥'} {thr:.2g} (α = 0.01, Bonferroni over 15), 15/16 blocks "
                  f"better: {verdict}",
          "test_rmse_before": None, "test_rmse_after": None, "test_rel_improvement": None}
    if test:
        ev.update(test_rmse_before=test[0], test_rmse_after=test[1], test_rel_improvement=1 - test[1] / test[0])
    return ev


def _hand_result(**over):
    rm = {"train": 0.5, "test": 0.6, "cv": 0.55}
    step = {"effect": "wind", "physical": "wind ≈ (1, 2) m/s", "coefficients": {}, "tested_jointly": None,
            "rmse": {"vx_dot": rm}, "evidence": _ev("wind", True, test=(0.50, 0.517))}
    d = {"targets": {"vx_dot": {"rmse_prior": rm, "rmse_before": rm, "rmse_after": rm, "steps": []}},
         "effects_added": ["wind"], "steps": [step], "untestable_reasons": {}, "not_detected": [],
         "conclusion": "added wind; no further effect is detectable from these signals",
         "final_effects": [{"effect": "wind", "physical": "wind ≈ (1, 2) m/s", "foldable": False,
                            "reason": "a condition of one flight", "features": {}}],
         "open_ended": {"vx_dot": {"ran": True, "passed": False, "equation": "13710.0*throttle**12",
                                   "signals": ["throttle"], "evidence": _ev("open-ended", False,
                                                                            test=(0.1, 0.6755))}},
         "candidates": [{"step": 1, "added": ["wind"], "scores": [
             {"effect": "wind", **{k: v for k, v in _ev("wind", True).items()}, "test_rmse_after": None},
             {"effect": "attitude_bias", **{k: v for k, v in _ev("attitude_bias", True).items()},
              "test_rmse_after": None}]}],
         "prior": "tilt-drag", "config": {}, "sources": {"train": ["a"], "test": ["b"]}}
    d.update(over)
    return d


def test_an_accepted_step_does_not_share_a_line_with_a_worse_test_error():
    txt = render_text(_hand_result())
    ev_line = next(x for x in txt.splitlines() if "evidence" in x and "wind: CV RMSE" in x)
    assert ev_line.rstrip().endswith("accepted") and "test" not in ev_line.split("wind:", 1)[1]
    assert "reported, not used" not in txt                       # the old, self-contradicting suffix
    assert ("test flights (reported only, not part of the decision): RMSE 0.5 -> 0.517 m/s² over all "
            "targets (+3.4 %, worse on the test flights)") in txt


def test_a_candidate_that_passes_but_is_not_added_does_not_say_accepted():
    lines = render_text(_hand_result()).splitlines()
    ab = next(x for x in lines if x.strip().startswith("attitude_bias: CV RMSE"))
    assert not ab.endswith("accepted") and "passes the rule, not added: wind was added" in ab
    w = next(x for x in lines if x.strip().startswith("wind: CV RMSE"))
    assert w.endswith("accepted: added")


def test_a_step_dropped_at_the_end_is_not_listed_as_added():
    d = _hand_result(effects_added=[], final_effects=[])
    d["steps"][0]["dropped"] = _ev("keep wind (all others in)", False, p=0.01)
    txt = render_text(d)
    assert "effects added, in order:" not in txt and "effects added: none in the end" in txt
    assert "1. wind: wind ≈ (1, 2) m/s — DROPPED at the end, not in the final model" in txt


def test_an_open_ended_term_that_is_not_significant_is_not_printed(tmp_path):
    d = _hand_result()
    assert "13710" not in render_text(d) and "+575" not in render_text(d)
    write(d, tmp_path / "rep")
    md = (tmp_path / "rep" / "diagnosis.md").read_text()
    assert "13710" not in md and "no significant residual remains" in md
    assert "passes the rule, not added" in md and "| added |" in md


def test_every_symbol_printed_is_explained():
    import re

    from droneid.report.diagnose import GLOSSARY
    txt = render_text(_result())
    assert "symbols:" in txt
    legend = txt[txt.index("symbols:"):]
    for sym, key in (("α", "α:"), ("σ", "σ:"), ("t = ", "t: the paired t"), ("sign-flip p", "sign-flip p:"),
                     ("Bonferroni over", "Bonferroni over m:"), ("CV", "CV:")):
        if sym in txt[:txt.index("symbols:")]:
            assert key in legend, sym
    # the glossary's patterns are valid and each names what it explains
    for pattern, meaning in GLOSSARY:
        re.compile(pattern)
        assert ":" in meaning
