"""droneid predict's result is typed and its report is rendered by the report package."""
import json
import math

from droneid.report import predict as predict_report
from droneid.use.score import Errors, HorizonErrors, Score, TargetScore


def _result(**kw):
    targets = {"vx_dot": TargetScore("vx_dot = -0.3·vx", ("vx",), ("a",),
                                     {"all": Errors(10, 0.25, rmse_empirical=math.nan)})}
    return Score(0.05, "central", targets, **kw)


def test_the_json_document_holds_only_what_was_measured():
    d = _result().to_dict()
    assert list(d) == ["ts", "method", "targets"]
    assert d["targets"]["vx_dot"]["errors"]["all"]["rmse_empirical"] is None   # strict JSON
    json.dumps(d, allow_nan=False)
    d = _result(fitness={"ok": True}, warnings=("slow signal",)).to_dict()
    assert d["warnings"] == ["slow signal"] and "horizons" not in d


def test_the_json_document_reads_back_into_the_same_score():
    res = _result(fitness={"ok": True}, warnings=("w",), horizons={"identified": {1: HorizonErrors(vx=0.1)}},
                  horizon_info={"dt_s": 0.01})
    back = Score.from_dict(json.loads(json.dumps(res.to_dict())))
    assert back.to_dict() == res.to_dict()
    assert back.horizons["identified"][1].vx == 0.1 and back.horizons["identified"][1].position is None
    e = back.targets["vx_dot"].errors["all"]
    assert e.n == 10 and e.rmse_identified == 0.25 and math.isnan(e.rmse_empirical) and e.rmse_refit is None


def test_the_open_loop_table_is_typed_and_reads_back():
    per = {"1": {"position": 0.004, "velocity": 0.01, "attitude": 0.003, "rates": 0.1},
           "simerr": {"position": 1.0, "velocity": 2.0, "attitude": 0.5, "rates": 9.0}}
    res = _result(open_loop={"identified": per, "constant": per})
    assert res.open_loop["identified"]["simerr"].rates == 9.0
    back = Score.from_dict(json.loads(json.dumps(res.to_dict())))
    assert back.open_loop == res.open_loop and back.to_dict() == res.to_dict()
    assert res.to_dict()["open_loop"] == {"identified": per, "constant": per}


def test_an_older_document_s_refit_error_reads_as_the_refit():
    """Documents written before the final models named the refit's error rmse_empirical_refit."""
    old = {"ts": 0.05, "method": "forward", "targets": {"vx_dot": {
        "equation": None, "inputs": ["vx"], "sources": ["a"],
        "errors": {"all": {"n": 3, "rmse_identified": 0.5, "rmse_empirical": 0.7, "rmse_empirical_refit": 0.6}}}}}
    new = {**old, "targets": {"vx_dot": {**old["targets"]["vx_dot"], "errors": {"all": {
        "n": 3, "rmse_identified": 0.5, "rmse_empirical": 0.7, "rmse_refit": 0.6}}}}}
    assert Score.from_dict(old) == Score.from_dict(new)
    assert Score.from_dict(old).targets["vx_dot"].errors["all"].rmse_refit == 0.6


def test_a_score_s_repr_is_a_summary():
    text = repr(_result())
    assert len(text.splitlines()) <= 4 and "vx_dot: n=10, RMSE final 0.25" in text


def test_the_text_report_has_a_table_per_target_and_leaves_the_warnings_to_stderr():
    """The warnings went to standard output, into a redirected report; the command prints them on
    standard error."""
    out = predict_report.text(_result(fitness={}, warnings=("slow signal",)))
    lines = out.splitlines()
    assert "slow signal" not in out and lines[0] == "== vx_dot: vx_dot = -0.3·vx"
    assert "e_d final model" in lines[1] and "0.25" in out and "multi-step" not in out


def test_the_open_loop_table_says_what_nominal_physics_is_and_why_1_step_positions_agree():
    """The whole-vehicle table showed 'nominal physics' undefined in the report and the same
    1-step position error for every moving model without saying why."""
    from droneid.report.predict import open_loop_lines
    from droneid.report.rotation import open_loop_legend
    legend = open_loop_legend(True)
    assert "nominal physics: thrust from the motor speeds" in legend
    assert "after 1 step a model that integrates moves the position by the logged start velocity" in legend
    assert "held between its updates" in legend
    per = {"1": {"position": 0.004, "velocity": 0.01, "attitude": 0.003, "rates": 0.1}}
    lines = open_loop_lines({"identified": per, "nominal physics": per, "constant": per}, rotation=False)
    assert open_loop_legend(False) in "\n".join(lines)


def test_identify_multistep_table_says_why_1_step_positions_agree():
    from droneid.report.identify import horizon_lines
    e = {"vx": 0.01, "position": 0.006888}
    h = {"rmse": {"identified": {"1": e}, "empirical": {"1": e}}, "steps": [1], "seconds": [0.01],
         "dt_s": 0.01, "n_starts": {"1": 100}}
    text = "\n".join(horizon_lines(h))
    assert "the 1-step position column measures the log" in text and "held between its updates" in text


def test_the_open_loop_table_has_a_verdict_first():
    """A user who reads only the first line learns whether the identified vehicle drifts less than
    holding the state, and where it does not, up to which horizon it is the better prediction and
    that held body rates are what drifts (log171 before this: SimErr 661 m against 310 held, no word)."""
    from droneid.simulation.drift import open_loop_verdict

    def rows(pos, att=1.0):
        return {"simerr": {"position": pos, "attitude": att}, "1": {"position": pos / 100},
                "10": {"position": pos / 10}, "50": {"position": pos}}
    best = open_loop_verdict({"identified": rows(1), "nominal physics": rows(3), "constant": rows(5)})
    assert best.startswith("open loop: the identified vehicle drifts least (position SimErr 1 m against 5")
    mid = open_loop_verdict({"identified": rows(4), "nominal physics": rows(3), "constant": rows(5)})
    assert "MORE than nominal physics (3)" in mid
    drift = rows(661, 40.5)
    drift["1"]["position"], drift["10"]["position"] = 0.03, 0.68
    said = open_loop_verdict({"identified": drift, "constant": rows(310, 17.5)}, rotation=False)
    assert "drifts FURTHER than the state held (position SimErr 661 m against 310" in said
    assert "up to 10 steps, not at 50" in said and "its body rates are held" in said
    assert "body rates are held" not in open_loop_verdict({"identified": drift, "constant": rows(310, 17.5)})
    assert open_loop_verdict({"constant": rows(1)}) == ""
    # predict's JSON says it too (the verdict lived in report/, which use/ does not import)
    full = {m: {h: {"velocity": 0.0, "attitude": 1.0, "rates": 0.0, **e} for h, e in per.items()}
            for m, per in {"identified": rows(1), "nominal physics": rows(3), "constant": rows(5)}.items()}
    d = _result(open_loop=full).to_dict()
    assert d["open_loop_verdict"] == best
