"""diagnose and identify make ONE plan (issue 40.1): on the same flights the same prior, the same
offset of the thrust inputs and the same effects; diagnose prints and records that plan as
identify does. A simulated flight whose logged motor speeds lead the speeds that act by 40 ms
(a Crazyflie-like clock offset) must be read 40 ms late by both."""
from __future__ import annotations

import pytest

from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose
from droneid.identify.pipeline import IdentifyConfig, plan_identification
from droneid.report.diagnose import text
from droneid.simulation.simulator import simulate

CFG = DiagnoseConfig(generations=0)


@pytest.fixture(scope="module")
def late_motors():
    """A climbing eight (thrust swings, so the offset shows in v̇z), motor speeds 40 ms ahead."""
    return simulate(path="eight", duration_s=30.0, rate_hz=50.0, seed=4, rpm_delay_s=0.04,
                    effects={"thrust_variation": {"amp_m": 0.3, "period_s": 2.0}}).flight


def test_diagnose_reads_the_motors_at_the_offset_identify_chooses(late_motors):
    res = diagnose([late_motors], prior="auto", config=CFG)
    plan = plan_identification([late_motors], IdentifyConfig.make(prior="auto"))
    assert plan.offset is not None and plan.offset.offset_s > 0, plan.notes
    # the planted 40 ms lies in the offset's interval
    lo, hi = plan.offset.interval_s
    assert lo <= 0.04 <= hi, plan.offset.interval_s
    # diagnose: the same prior, the same offset (and interval), recorded as identify records it
    assert res.plan["prior_used"] == plan.prior.name
    assert res.plan["prior_params"] == dict(plan.prior.params)
    assert res.plan["offset"]["offset_s"] == plan.offset.offset_s
    assert res.plan["offset"]["interval_s"] == list(plan.offset.interval_s)
    assert res.plan["delays_s"] == plan.delays_s
    # the same catalogue decisions
    assert res.effects_added == plan.diagnosis["effects_added"]
    # printed: the plan's offset line in diagnose's terminal summary, word for word identify's
    out = text(res)
    assert plan.offset.text(sorted(plan.delays_s)) in out
    assert f"prior: {plan.prior.name} ({plan.prior_reason})" in out


def test_the_plan_survives_diagnosis_json(late_motors):
    from droneid.diagnosis.result import DiagnosisResult
    res = diagnose([late_motors], prior="auto", config=CFG)
    back = DiagnosisResult.from_dict(res.to_dict())
    assert back.plan["offset"]["offset_s"] == res.plan["offset"]["offset_s"] > 0
    assert back.plan["lines"] == res.plan["lines"]
