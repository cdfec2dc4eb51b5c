"""The study's typed result (:class:`droneid.identify.study.StudyResult`): ``to_dict`` is the study.json
document, ``from_dict`` reads it back, a document that is not a study result is refused in one
line, and the report renders the object and its JSON alike. Built by hand (no SNGP run)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from droneid.errors import DataError, DroneIdError
from droneid.identify.pipeline import RunRecord
from droneid.identify.study import (PRIOR_VARIANTS, RUN_KEYS, SCENARIOS, STUDY_SCHEMA, StudyResult, StudyTarget,
                           StudyVariant, variant_key)


def _run(seed: int, e_test: float, qualified: bool = True) -> RunRecord:
    """A full run record, as a worker returns it (model, archive and predictions included)."""
    return RunRecord(target="vx_dot", variant="x", index=seed, seed=seed, rmse_train=np.float64(0.1 + 0.01 * seed),
                     rmse_test=e_test, constraint_rmse_train=math.nan, constraint_rmse_test=0.02,
                     qualified=qualified, equation=f"{seed}*x", equation_expanded=f"{seed}.0*x",
                     wall_s=0.5, generations=50, archive=({"rmse_train": 0.1, "constraint_rmse_train": None},),
                     model={"format": "droneid.sngp/1"}, pred_test=np.zeros(3))


def _result(interrupted: bool = False) -> StudyResult:
    targets = {}
    for t in ("vx_dot", "vy_dot"):
        variants = {}
        for scenario, _ in SCENARIOS:
            for k in PRIOR_VARIANTS:
                runs = [_run(s, 0.3 - 0.05 * k + 0.01 * s) for s in range(3)]
                if k == 3:
                    runs.append(_run(9, math.inf))     # a diverged run: test error not finite
                variants[variant_key(scenario, k)] = StudyVariant.from_runs(
                    scenario, k, runs, failed=["ValueError: boom"] if k == 1 else (),
                    p_value_vs_no_prior=None if k == 0 else (math.nan if scenario == "constrained" else 0.04))
        targets[t] = StudyTarget(n_train=160, n_test=251, test_data="test flights: square",
                                 notes=("a note",),
                                 empirical={"rmse_train": 0.2, "rmse_test": np.float64(0.21),
                                            "constraint_rmse_test": 0.0, "equation": "-0.28*vx", "expr": "-0.28*vx"},
                                 empirical_refit={"rmse_train": 0.19, "rmse_test": 0.2,
                                                  "constraint_rmse_test": math.nan,
                                                  "coefficients": {"drag": -0.3}, "intercept": 0.0},
                                 variants=variants)
    return StudyResult(targets=targets, config={"runs": 3, "generations": 50, "population_size": 40, "seed": 0,
                                                "prior": "tilt-drag", "constraints": "paper"},
                       provenance={"train": [{"path": "a.tlog"}], "test": []}, versions={"droneid": "0"},
                       interrupted=interrupted, backend="inprocess", runs_total=40, runs_finished=38, wall_s=1.5)


def test_round_trip_through_json_gives_the_same_document():
    res = _result()
    doc = res.to_dict()
    back = StudyResult.from_dict(json.loads(json.dumps(doc, allow_nan=False)))
    assert back.to_dict() == doc
    assert json.dumps(back.to_dict()) == json.dumps(doc)          # same key order too
    assert isinstance(back.targets["vx_dot"], StudyTarget)
    v = back.targets["vx_dot"].variant("baseline", 1)
    assert isinstance(v, StudyVariant) and all(isinstance(r, RunRecord) for r in v.runs)
    assert v.failed == ("ValueError: boom",) and v.n_runs == 3


def test_document_keeps_the_study_json_schema():
    doc = _result().to_dict()
    assert list(doc) == ["schema", "targets", "config", "provenance", "versions", "interrupted", "backend",
                         "runs_total", "runs_finished", "wall_s"]
    assert doc["schema"] == STUDY_SCHEMA == StudyResult.schema
    tr = doc["targets"]["vx_dot"]
    assert list(tr) == ["n_train", "n_test", "test_data", "notes", "empirical", "empirical_refit", "variants"]
    assert list(tr["variants"]) == [variant_key(s, k) for s, _ in SCENARIOS for k in PRIOR_VARIANTS]
    v = tr["variants"]["constrained/3"]
    assert list(v) == ["scenario", "prior_features", "n_runs", "failed", "median_rmse_train", "median_rmse_test",
                       "median_constraint_rmse_test", "best_equation", "runs", "p_value_vs_no_prior"]
    assert all(list(r) == list(RUN_KEYS) for r in v["runs"])      # summaries: no model, archive, predictions
    assert v["runs"][-1]["rmse_test"] is None                      # inf written as null
    assert v["p_value_vs_no_prior"] is None                         # NaN written as null
    assert tr["variants"]["baseline/0"]["p_value_vs_no_prior"] is None
    assert tr["empirical_refit"]["constraint_rmse_test"] is None
    json.dumps(doc, allow_nan=False)                                # strict JSON


def test_variant_medians_and_best_run_come_from_the_runs():
    v = _result().targets["vx_dot"].variant("baseline", 3)
    assert v.key == "baseline/3" and v.n_runs == 4
    assert v.median_rmse_test == pytest.approx(np.median([0.15, 0.16, 0.17]))   # inf skipped
    assert v.best_equation == "0*x"                                  # lowest TRAINING error
    assert all(r.model is None and r.pred_test is None and r.archive == () for r in v.runs)


def test_from_dict_reads_nulls_back_as_nan_and_none():
    back = StudyResult.from_dict(_result().to_dict())
    tr = back.targets["vy_dot"]
    assert tr.variant("baseline", 0).p_value_vs_no_prior is None
    assert math.isnan(tr.variant("constrained", 1).p_value_vs_no_prior)
    assert tr.variant("baseline", 1).p_value_vs_no_prior == 0.04
    assert math.isnan(tr.variant("constrained", 3).runs[-1].rmse_test)
    assert tr.notes == ("a note",) and back.runs_finished == 38 and back.backend == "inprocess"


def _bad(doc_edit):
    doc = _result().to_dict()
    doc_edit(doc)
    return doc


@pytest.mark.parametrize("doc, words", [
    ([1, 2], "a JSON list"),
    ("study", "a JSON str"),
    ({"targets": {}}, "schema None"),
    ({"schema": "droneid.identify/1", "targets": {}}, "schema 'droneid.identify/1'"),
    ({"schema": STUDY_SCHEMA}, "no 'targets'"),
    ({"schema": STUDY_SCHEMA, "targets": [1]}, "no 'targets'"),
    (_bad(lambda d: d["targets"].update(vx_dot=[])), "target 'vx_dot'"),
    (_bad(lambda d: d["targets"]["vx_dot"].pop("variants")), "no 'variants'"),
    (_bad(lambda d: d["targets"]["vy_dot"]["variants"]["baseline/1"].pop("scenario")),
     "target 'vy_dot': variant 'baseline/1'"),
    (_bad(lambda d: d["targets"]["vx_dot"]["variants"]["baseline/3"].update(prior_features="three")),
     "variant 'baseline/3'"),
    (_bad(lambda d: d["targets"]["vx_dot"]["variants"]["baseline/0"]["runs"].append("run")),
     "a study run must be an object"),
    (_bad(lambda d: d.update(runs_total="many")), "not a study result"),
])
def test_a_document_that_is_not_a_study_result_is_refused_in_one_line(doc, words):
    with pytest.raises(DataError) as info:
        StudyResult.from_dict(doc)
    msg = str(info.value)
    assert msg.startswith("not a study result") and words in msg and "\n" not in msg
    assert isinstance(info.value, (DroneIdError, ValueError))


def test_report_renders_the_result_and_its_json_alike(tmp_path):
    from droneid.report import study as report
    res = _result(interrupted=True)
    doc = json.loads(json.dumps(res.to_dict()))
    assert report.study_table(res) == report.study_table(doc)
    text = report.text(res)
    assert text == report.text(doc)
    assert "NOTE: interrupted; 38 of 40 runs finished" in text and "  NOTE: a note" in text
    header, rows = report.study_table(res)
    assert len(header) == 2 + 3 * 2 and len(rows) == 8
    assert rows[1][4] == "0.04 (lower)" and rows[5][4] == "— (lower)"     # p-value and direction
    paths = report.write(res, tmp_path / "study")
    assert json.loads(paths["study.json"].read_text()) == res.to_dict()
    assert {"study_vx_dot.png", "study_vy_dot.png"} <= {p.name for p in (tmp_path / "study").iterdir()}


def test_report_refuses_a_document_of_another_kind():
    from droneid.report import study as report
    with pytest.raises(DataError, match="not a study result"):
        report.text({"schema": "droneid.identify/1", "targets": {}})
