"""Priors declare their own physics (issue 27): a thrust-based prior added as one module
(tests/plugins/lifting_body.py, named nowhere in droneid) gets hover calibration and its own
constraint set, with no line of the pipeline testing its name."""
from pathlib import Path

import numpy as np
import pytest

from droneid.api import read_log
from droneid.diagnosis.diagnose import plan_identification
from droneid.planning.plan import dataset_builder
from droneid.identify.problem import prepare_target
from droneid.planning.settings import IdentifyConfig
from plugins.lifting_body import lifting_body

SAMPLE = Path(__file__).resolve().parents[2] / "sample_logs" / "rotor_climb_eight.flat.csv"


@pytest.fixture(scope="module")
def planned():
    flights = [read_log(SAMPLE)]
    prior = lifting_body()
    cfg = IdentifyConfig.make(prior=prior, effects="none", delays="none", targets="vx_dot,vz_dot")
    return flights, prior, cfg, plan_identification(flights, cfg)


def test_the_new_prior_is_hover_calibrated(planned):
    flights, prior, cfg, plan = planned
    assert plan.prior.name == "lifting-body"
    assert plan.prior.params["k_T"] != pytest.approx(prior.params["k_T"], rel=0.01)
    # hover balance: over the flight the median vertical thrust term is g, from inputs only
    ds = dataset_builder(cfg).build(flights, target="vz_dot", inputs=plan.prior.inputs("vz_dot"))
    lift = plan.prior.evaluate(ds.columns(), "vz_dot")[:, 0]
    assert float(np.median(lift)) == pytest.approx(9.81, rel=1e-9)
    assert plan.prior.thrust_signals("vx_dot") == ["rpm1", "rpm2", "rpm3", "rpm4"]


def test_the_new_prior_brings_its_own_constraints_built_from_the_data(planned):
    flights, _, cfg, plan = planned
    p = prepare_target(flights, None, "vz_dot", cfg, plan)
    assert p.constraint_set.name == "lifting-body free fall"
    (c,) = p.constraint_set.constraints
    assert c.value == pytest.approx(-9.81) and c.domain["rpm1"] == 0.0
    # horizontal targets: its set plus the drag-sign constraints over the thrust span it gave
    px = prepare_target(flights, None, "vx_dot", cfg, plan)
    assert px.constraint_set.name == "lifting-body free fall+drag-sign"
    top = max(float(np.max(px.train.columns()[f"rpm{i}"])) for i in range(1, 5))
    assert max(c.domain["rpm1"][1] for c in px.constraint_set.constraints[1:]) <= top


def test_the_result_records_the_prior_by_name():
    cfg = IdentifyConfig.make(prior=lifting_body())
    assert cfg.to_dict()["prior"] == "lifting-body"
