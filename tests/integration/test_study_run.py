"""A tiny real study returns a :class:`droneid.identify.study.StudyResult` whose study.json reads back to
the same document (simulated flight with planted truth; budgets of seconds)."""
from __future__ import annotations

import json
import math

from droneid.identify.pipeline import IdentifyConfig, RunRecord
from droneid.identify.study import PRIOR_VARIANTS, RUN_KEYS, SCENARIOS, StudyResult, variant_key


def test_a_tiny_study_is_typed_and_round_trips_through_study_json(tmp_path):
    from droneid.report import study as report
    from droneid.simulation.simulator import simulate
    from droneid.identify.study import study
    train = simulate(path="eight", duration_s=8.0, seed=11).flight
    test = simulate(path="square", duration_s=8.0, seed=12).flight
    cfg = IdentifyConfig.make(targets=("vx_dot",), runs=2, generations=50, population_size=40, jobs=1, seed=0)
    res = study([train], [test], cfg)
    assert isinstance(res, StudyResult) and not res.interrupted
    assert res.runs_total == res.runs_finished == len(SCENARIOS) * len(PRIOR_VARIANTS) * 2
    tr = res.targets["vx_dot"]
    assert list(tr.variants) == [variant_key(s, k) for s, _ in SCENARIOS for k in PRIOR_VARIANTS]
    for v in tr.variants.values():
        assert v.n_runs == 2 and not v.failed
        assert all(isinstance(r, RunRecord) and r.model is None for r in v.runs)   # summaries only
        assert math.isfinite(v.median_rmse_test)
        assert (v.p_value_vs_no_prior is None) == (v.prior_features == 0)
    assert res.config["effects"] == "none" and res.config["simplify_s"] == 0.0
    doc = res.to_dict()
    assert all(list(r) == list(RUN_KEYS) for v in doc["targets"]["vx_dot"]["variants"].values() for r in v["runs"])
    paths = report.write(res, tmp_path / "study")
    written = json.loads(paths["study.json"].read_text())
    assert written == doc
    assert StudyResult.from_dict(written).to_dict() == doc


def test_the_study_runs_a_user_toml_prior_and_records_its_spec():
    """--prior FILE.toml:NAME reaches every target's problem (not only the first resolution)."""
    from pathlib import Path

    from droneid.simulation.simulator import simulate
    from droneid.identify.study import study
    spec = f"{Path(__file__).resolve().parents[2] / 'priors' / 'example_priors.toml'}:tilt-quadratic-drag"
    train = simulate(path="eight", duration_s=8.0, seed=11).flight
    cfg = IdentifyConfig.make(targets=("vx_dot",), runs=1, generations=30, population_size=40, jobs=1,
                              seed=0, prior=spec)
    res = study([train], None, cfg)
    assert res.runs_finished == len(SCENARIOS) * len(PRIOR_VARIANTS) and res.config["prior"] == spec
    default = study([train], None, IdentifyConfig.make(targets=("vx_dot",), runs=1, generations=30,
                                                      population_size=40, jobs=1, seed=0))
    assert default.config["prior"] == "tilt-drag"          # auto means the paper's prior in the study
