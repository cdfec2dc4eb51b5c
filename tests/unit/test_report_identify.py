"""Identification reports and selection, tested from hand-built results (no engine needed)."""
from __future__ import annotations

import json
import re
import math
from dataclasses import replace

import numpy as np
import pytest

from droneid.errors import ConfigError, DataError
from droneid.fitting.closed_form import IdentifiedModel
from droneid.identify.pipeline import (FeatureText, IdentificationResult, IdentifyConfig, PlanRecord, RunRecord,
                              TargetResult)
from droneid.identify.ladder import GuardReport, Interval, Rung
from droneid.report.identify import pareto_front, write
from droneid.report.identify import text as render_text
from droneid.core.text import display_term, improvement_pct, readable_equation
from droneid.identify.search import run_seeds, select_best

SIGNALS = ["vx", "pitch", "roll", "yaw", "rpm1", "rpm2", "rpm3", "rpm4"]


def _model(expr: str, delays=None, description="") -> IdentifiedModel:
    return IdentifiedModel.from_dict({"target": "vx_dot", "expr": expr, "signals": SIGNALS,
                                      "delays_s": delays or {}, "description": description})


def _rung(name, description, e, model, **kw) -> Rung:
    return Rung(name, description, e, e, e, 0.01, {"⟨tilt_pitch⟩": 0.9, "vx": -0.3}, 0.0, model, **kw)


def hand_built(constraints="paper", final_expr="8.8*tan(pitch) - 0.3*vx", delays=None) -> IdentificationResult:
    """A typed result as identify makes it (no engine needed)."""
    t = np.arange(0, 5, 0.05)
    y = np.sin(t)
    runs = tuple(RunRecord(seed=10 + i, rmse_train=0.1 + 0.01 * i, rmse_test=0.2 + 0.02 * i,
                           constraint_rmse_train=0.01 * (i + 1), constraint_rmse_test=0.02 * (i + 1),
                           qualified=True, wall_s=1.5, generations=100, equation="x",
                           archive=tuple({"rmse_train": 0.1 + j * 0.01, "constraint_rmse_train": 0.5 / (j + 1)}
                                         for j in range(5))) for i in range(4))
    emp = _model("9.81*tan(pitch) - 0.28*vx", description="the empirical tilt-drag model as given")
    ladder = (_rung("empirical", "the empirical tilt-drag model as given", 0.3, emp),
              _rung("refit", "tilt-drag prior refit", 0.2, _model("9.3*tan(pitch) - 0.25*vx")),
              _rung("final", "= the rung above", 0.2, _model(final_expr, delays),
                    intervals={"⟨tilt_pitch⟩": Interval(0.85, 0.95)}, held={}))
    tr = TargetResult(
        target="vx_dot", inputs=("vx", "pitch", "roll", "yaw"), n_train=160, n_test=100,
        test_data="test flights: square", holdout=False,
        constraints="none" if constraints == "none" else "paper+drag-sign",
        prior_features=(FeatureText("tilt_pitch", "9.81*tan(pitch)", "d"),), empirical_terms=(),
        ladder=ladder, guards=GuardReport(bound=20.0, candidates=1, chosen_run=0),
        verdict="vx_dot: the physical model is 33 % better than the empirical model on the test flights",
        verdict_kind="better", equation="vx_dot = 0.9·⟨tilt_pitch⟩ - 0.3·vx",
        identified={"rmse_train": 0.1, "rmse_test": 0.2, "constraint_rmse_test": 0.02},
        empirical={"rmse_train": 0.5, "rmse_test": 0.4, "constraint_rmse_test": 0.0},
        empirical_refit={"rmse_train": 0.3, "rmse_test": 0.25, "constraint_rmse_test": 0.001,
                         "coefficients": {"tilt_pitch": 0.95}, "intercept": 0.01},
        runs=runs, test_series={"t": t.tolist(), "flight": [0] * t.size, "y": y.tolist(),
                                "empirical": (0.8 * y).tolist(), "empirical_refit": (0.9 * y).tolist(),
                                "identified": (0.97 * y).tolist()},
        notes=("test flights: square",), intervals={"tilt_pitch": Interval(0.85, 0.95)})
    return IdentificationResult({"vx_dot": tr}, IdentifyConfig(constraints=constraints),
                                PlanRecord(prior_used="tilt-drag", validation="leave-one-flight-out"),
                                {"train": [{"files": ["eight.tlog"]}], "test": [{"files": ["square.tlog"]}]},
                                {"droneid": "0"}, wall_s=1.0)


def hand_built_result(constraints="paper") -> dict:
    """The result.json document of :func:`hand_built`."""
    return hand_built(constraints).to_dict()


def test_text_summary_has_verdict_equation_ladder_and_the_constraints_used():
    text = render_text(hand_built_result())
    assert "vx_dot = 0.9·⟨tilt_pitch⟩ - 0.3·vx" in text
    assert "⟨tilt_pitch⟩ = 9.81*tan(pitch)" in text
    assert text.index("33 % better") < text.index("vx_dot = 0.9") < text.index("FINAL: = the rung above")
    assert "constraints paper+drag-sign (the prior's own" in text
    assert "⟨tilt_pitch⟩ 0.9 [0.85, 0.95]" in text        # the interval beside the coefficient


def test_a_result_of_the_first_version_is_refused_in_one_line():
    d = hand_built_result()
    d["schema"] = "droneid.identify/1"
    with pytest.raises(DataError, match="re-run `droneid identify`"):
        IdentificationResult.from_dict(d)
    with pytest.raises(DataError, match="re-run"):
        render_text(d)


def test_write_result_writes_json_markdown_html_and_pngs(tmp_path):
    paths = write(hand_built_result(), tmp_path)
    names = {p.name for p in tmp_path.iterdir()}
    assert {"result.json", "report.md", "report.html", "vx_dot_test_prediction.png", "vx_dot_residuals.png",
            "vx_dot_runs.png", "vx_dot_pareto.png"} <= names
    assert json.loads((tmp_path / "result.json").read_text())["targets"]["vx_dot"]["equation"]
    html = (tmp_path / "report.html").read_text()
    assert html.count("data:image/png;base64,") == 5 and "<table>" in html  # + the typeset equation
    assert "![" in (tmp_path / "report.md").read_text()
    assert not [n for n in names if n.endswith(".tmp")]
    assert paths["json"].name == "result.json"


def test_no_pareto_figure_without_constraints(tmp_path):
    write(hand_built_result(constraints="none"), tmp_path)
    assert not (tmp_path / "vx_dot_pareto.png").exists()


def test_result_round_trips_through_from_dict():
    d = json.loads(json.dumps(hand_built_result()))
    back = IdentificationResult.from_dict(d)
    assert back.targets["vx_dot"] == hand_built().targets["vx_dot"]
    assert json.loads(json.dumps(back.to_dict())) == d


def test_select_best_uses_training_error_of_qualified_runs_only():
    runs = [RunRecord(rmse_train=0.1, rmse_test=9.0, qualified=False, constraint_rmse_train=1.0),
            RunRecord(rmse_train=0.3, rmse_test=0.1, qualified=True, constraint_rmse_train=0.01),
            RunRecord(rmse_train=0.2, rmse_test=5.0, qualified=True, constraint_rmse_train=0.04),
            None]
    assert select_best(runs[:3]) == 2        # lowest train error among qualified, test ignored
    none_ok = [replace(r, qualified=False) for r in runs[:3]]
    assert select_best(none_ok) == 1         # none qualified: lowest training constraint error
    assert select_best([None, None]) is None


def test_readable_equation_names_priors_and_signs():
    eq = readable_equation("vy_dot", {"vy": -0.25, "sin(roll)": 0.125}, {"tilt": 1.02}, -0.01)
    assert eq == "vy_dot = 1.02·⟨tilt⟩ - 0.25·vy + 0.125·sin(roll) - 0.01"


def test_pareto_front_mask():
    pts = np.array([[1, 5], [2, 2], [3, 3], [5, 1], [2, 6]])
    assert pareto_front(pts).tolist() == [True, True, False, True, False]


def test_improvement_pct():
    assert improvement_pct(0.4, 0.2) == 50.0
    assert math.isnan(improvement_pct(float("nan"), 0.2))


def test_run_seeds_are_prefix_stable():
    t1, s1 = run_seeds(7, 3)
    t2, s2 = run_seeds(7, 10)
    assert t1 == t2 and s1 == s2[:3] and len(set(s2)) == 10


@pytest.mark.parametrize("given, match", [
    ({"targets": "vx_dott"}, "did you mean 'vx_dot'"),
    ({"prior_features": 2}, "prior_features"),
    ({"constraints": "/nonexistent.toml"}, "constraints"),
    ({"runs": 0}, "'runs'"),
    ({"method": "backward"}, "method"),
])
def test_config_rejects_bad_values(given, match):
    with pytest.raises(ConfigError, match=match):
        IdentifyConfig.make(**given)


def test_config_quick_budget_and_overrides():
    q = IdentifyConfig.make(quick=True, runs=2)
    assert q.quick and q.runs == 2 and q.generations < 60000
    p = IdentifyConfig.make(targets="vx_dot,vy_dot")
    assert p.generations == 60000 and p.population_size == 500 and p.targets == ("vx_dot", "vy_dot")


def test_readable_equation_shows_prior_symbols_by_name_and_rounds():
    syms = {"P2_g_sin": "g_sin", "P1_a": "a"}
    assert display_term("-sin(357.0494022507776*P2_g_sin)", syms) == ("sin(357*⟨g_sin⟩)", True)
    assert display_term("-P1_a**2 + cos(P2_g_sin)", syms) == ("(-⟨a⟩**2 + cos(⟨g_sin⟩))", False)
    eq = readable_equation("vx_dot", {"-sin(P1_a)": -0.5, "vx**2": 0.25, "8.0*P1_a*vx": 0.5}, {"a": 1.0},
                           0.0, syms)
    assert eq == "vx_dot = 1·⟨a⟩ + 0.5·sin(⟨a⟩) + 0.25·vx**2 + 4·⟨a⟩*vx"


# ------------------------------------------------------------------------------------------------
# reports that read at a glance (issue 13 item 5)

LONG_EXPR = ("-0.282747590081903*vx + 0.996674873717764*(sin(pitch)*cos(roll)*cos(yaw) + sin(roll)*sin(yaw))"
             "*(1.08996582798623e-8*rpm1**2 + 1.08996582798623e-8*rpm2**2 + 1.08996582798623e-8*rpm3**2"
             " + 1.08996582798623e-8*rpm4**2) - 0.00227831391289888")


def ladder_result(gap: bool = True) -> dict:
    """The hand-built result with a long final model that reads its motor speeds 100 ms early,
    and (``gap``) a 3 s gap in the test flight's time (the vehicle on the ground)."""
    r = hand_built_result()
    if gap:
        tr = r["targets"]["vx_dot"]
        t = np.asarray(tr["test_series"]["t"])
        tr["test_series"]["t"] = np.where(t >= 2.5, t + 3.0, t).tolist()
    final = hand_built(final_expr=LONG_EXPR, delays={"rpm1": 0.1}).targets["vx_dot"].ladder[-1]
    r["targets"]["vx_dot"]["ladder"][-1] = final.to_dict()
    return r


def ladder_target(gap: bool = True) -> TargetResult:
    return IdentificationResult.from_dict(ladder_result(gap)).targets["vx_dot"]


def _lines(fig):
    return [ln for ax in fig.axes for ln in ax.get_lines()]


def test_html_starts_each_target_with_the_verdict_then_equation_and_plot_then_the_ladder(tmp_path):
    write(ladder_result(), tmp_path)
    html = (tmp_path / "report.html").read_text()
    i_verdict = html.index("class='verdict green'>vx_dot: the physical model is 33 %", html.index("<h2>vx_dot</h2>"))
    i_eq = html.index("alt='vx_dot_equation'")
    i_plot = html.index("alt='vx_dot_test_prediction'")
    i_ladder = html.index("the empirical tilt-drag model as given")
    assert html.index("<h2>vx_dot</h2>") < i_verdict < i_eq < i_plot < i_ladder
    # equation and comparison plot share one row (side by side)
    row = html[html.rindex("<div class='row'>", 0, i_eq):]
    assert row.index("alt='vx_dot_test_prediction'") < row.index("</div>")
    assert (tmp_path / "vx_dot_equation.png").read_bytes()[:4] == b"\x89PNG"
    md = (tmp_path / "report.md").read_text()
    assert md.index("**vx_dot: the physical model") < md.index("the empirical tilt-drag model as given")


def test_html_puts_every_verdict_before_the_notes_which_are_folded(tmp_path):
    """On the squares ten NOTE paragraphs pushed the first verdict below the first screen."""
    r = ladder_result()
    r["notes"] = [f"planted note {i}" for i in range(10)]
    r["targets"]["vx_dot"]["notes"] = list(r["targets"]["vx_dot"]["notes"]) + ["a target note"]
    write(r, tmp_path)
    html = (tmp_path / "report.html").read_text()
    first_verdict = html.index("class='verdict")
    assert first_verdict < html.index("planted note 0") and first_verdict < html.index("<h2>vx_dot</h2>")
    assert html.count("class='verdict") >= 2 * len(r["targets"])       # summary, then each section
    notes = html[html.rindex("<details", 0, html.index("planted note 0")):]
    assert notes.startswith("<details class='notes'><summary>10 note(s)") and \
        notes.index("planted note 9") < notes.index("</details>")
    assert "<p>NOTE: a target note</p>" in html[html.rindex("<details", 0, html.index("a target note")):]
    # numbers in table cells never wrap inside themselves (0.004137 was split over two lines)
    css = html[html.index("<style>"):html.index("</style>")]
    assert "td,th{" in css and "white-space:nowrap" in css.split("td,th{")[1].split("}")[0]
    md = (tmp_path / "report.md").read_text()
    assert md.index("planted note 9") > md.index("**vx_dot: the physical model")


def test_text_output_keeps_verdict_equation_ladder_order():
    text = render_text(ladder_result())
    assert text.index("33 % better") < text.index("expanded:") < text.index("FINAL: = the rung above")
    assert "offset inputs: rpm1(t − 100 ms)" in text


def test_long_equation_is_wrapped_into_lines_of_bounded_length():
    from droneid.report.identify import _math_lines, fig_equation
    lines = _math_lines("vx_dot", LONG_EXPR, width=110)
    assert len(lines) >= 2 and all(len(ln) < 110 + 60 for ln in lines)
    assert lines[0].startswith(r"$\dot{v}_{x} = ") and "0.2827" in "".join(lines)
    assert "0.282747590081903" not in "".join(lines)  # numbers rounded to 4 significant figures
    assert _math_lines("vx_dot", "__import__('os').system('false')") is None  # parsed safely, never eval'd
    fig = fig_equation("vx_dot", ladder_target())
    w, h = fig.get_size_inches()
    assert w <= 10 and h >= 2 * 0.42  # wrapped, not one very wide line


def test_plots_break_the_line_at_a_gap_in_time():
    from droneid.report.identify import fig_measured_vs_predicted, fig_residuals
    tr = ladder_target(gap=True)
    for fig in (fig_measured_vs_predicted("vx_dot", tr), fig_residuals("vx_dot", tr)):
        for ln in [ln for ln in _lines(fig) if len(ln.get_xdata()) > 2]:
            x, y = np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float)
            k = int(np.flatnonzero(np.isnan(y))[0])
            assert np.isnan(y).sum() == 1 and x[k - 1] < 2.5 and x[k + 1] >= 5.5
    tr = ladder_target(gap=False)
    assert not any(np.isnan(np.asarray(ln.get_ydata(), float)).any() for ln in
                   _lines(fig_measured_vs_predicted("vx_dot", tr)))


def test_break_gaps_splits_flights_and_time_jumps():
    from droneid.report.document import break_gaps
    x, (y,) = break_gaps(np.arange(6.0), [np.ones(6)], t=[0, .1, .2, 9, 9.1, 0.05], flight=[0, 0, 0, 0, 0, 1])
    assert np.flatnonzero(np.isnan(y)).tolist() == [3, 6] and np.isnan(x[[3, 6]]).all()


def test_every_axis_of_the_report_figures_has_a_unit():
    from droneid.report import identify as R
    tr = ladder_target()
    figs = [R.fig_measured_vs_predicted("vx_dot", tr), R.fig_residuals("vx_dot", tr), R.fig_runs("vx_dot", tr),
            R.fig_pareto("vx_dot", tr, 0.1)]
    unit = re.compile(r"\((s|m/s²|m/s\^2|m/s)\)|sorted")
    for fig in figs:
        for ax in fig.axes:
            assert unit.search(ax.get_xlabel()), ax.get_xlabel()
            assert unit.search(ax.get_ylabel()), ax.get_ylabel()


def test_prior_feature_legend_is_readable():
    """The legend pulls the common thrust scale out of the rotor sum and rounds it; the saved
    expression is untouched, and text the safe parser refuses is never evaluated."""
    from droneid.report.identify import readable_expr
    full = ("(sin(pitch)*cos(roll))*(2.56595388352325e-10*rpm1**2 + 2.56595388352325e-10*rpm2**2"
            " + 2.56595388352325e-10*rpm3**2 + 2.56595388352325e-10*rpm4**2)")
    shown = readable_expr(full)
    assert shown.count("2.566e-10") == 1 and "rpm1**2 + rpm2**2 + rpm3**2 + rpm4**2" in shown
    assert readable_expr("-0.28*vx") == "-0.28*vx"
    assert readable_expr("9**9**9*vx") == "9**9**9*vx"  # refused by the parser: shown as is


def test_a_run_record_survives_json_and_keeps_its_summary_keys():
    r = RunRecord(target="vx_dot", index=2, seed=7, rmse_train=0.25, rmse_test=0.5, equation="vx_dot = P1",
                  archive=({"rmse_train": 0.3, "constraint_rmse_train": 0.1},), model={"equation": "P1"},
                  pred_test=np.array([1.0, 2.0]), prior_symbols={"P1": "tilt"})
    back = RunRecord.from_dict(json.loads(json.dumps(r.to_dict())))
    assert back.to_dict() == r.to_dict() and np.array_equal(back.pred_test, r.pred_test)
    assert math.isnan(back.constraint_rmse_test) and back.archive == r.archive  # null -> NaN, list -> tuple
    s = r.summary()
    assert set(s) == set(RunRecord.SUMMARY_KEYS) and "pred_test" not in s and "model" not in s
    assert s["archive"] == [{"rmse_train": 0.3, "constraint_rmse_train": 0.1}]
    with pytest.raises(Exception, match="not a run record"):
        RunRecord.from_dict([1, 2])


@pytest.mark.slow
def test_the_verdict_box_colour_follows_the_verdict(tmp_path):
    """Green only for "better"; a model not to be trusted is amber, a worse one red."""
    for kind, colour in (("better", "green"), ("no better", "grey"), ("worse", "red"),
                         ("not to be trusted", "amber"), ("no verdict", "grey")):
        res = ladder_result()
        res["targets"]["vx_dot"]["verdict_kind"] = kind
        write(res, tmp_path)
        html = (tmp_path / "report.html").read_text()
        assert f"class='verdict {colour}'>" in html
        assert html.count("class='verdict ") == 2 and html.count(f"class='verdict {colour}'>") == 2  # summary + section
