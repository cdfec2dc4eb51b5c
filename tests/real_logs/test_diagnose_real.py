"""Diagnosis on the real Crazyflie flights: the test flights (melon) never change the result, and
the call the identify pipeline makes (rotor-thrust prior, per-target Datasets) works."""
from __future__ import annotations

import pytest

from conftest import real_log
from droneid.dataset.builder import DatasetBuilder
from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose, diagnose_datasets
from diag_synth import decisions
from priors.registry import get_prior

pytestmark = [pytest.mark.slow, pytest.mark.real_logs]
CF = "mocap/crazyflie_nanodrone/"
CFG = DiagnoseConfig(generations=0)


def _flights(names):
    import parsers
    return [parsers.read_flight(real_log(CF + n)) for n in names]


def test_crazyflie_squares_same_result_with_and_without_melon():
    train = _flights([f"square_run{i}.csv" for i in range(1, 6)])
    test = _flights(["melon_run1.csv", "melon_run4.csv"])
    a = diagnose(train, None, prior="tilt-drag", config=CFG)
    b = diagnose(train, test, prior="tilt-drag", config=CFG)
    assert decisions(a) == decisions(b)
    assert all(v["rmse_after"]["test"] is not None for v in b.targets.values())
    # the finding, now from causal inputs: thrust variation, built from the logged
    # motor speeds (not from v̇z or az); more thrust, more acceleration (gain > 0)
    assert a.effects_added[:1] == ["thrust_variation"]
    fe = a.final_effects[0]
    assert fe["physical_values"]["gain"] > 0
    used = {s.name for fs in fe["features"].values() for f in fs for s in f["expr"].free_symbols}
    assert {"rpm1", "rpm2", "rpm3", "rpm4"} <= used and not used & {"vz", "az", "vz_dot"}


def test_identify_call_with_the_rotor_thrust_prior_on_the_squares():
    prior = get_prior("rotor-thrust", source="rpm", motors=4)
    b = DatasetBuilder(ts=0.05, method="central")
    train_fl = _flights([f"square_run{i}.csv" for i in range(1, 6)])
    test_fl = _flights(["melon_run1.csv", "melon_run4.csv"])
    targets = ("vx_dot", "vy_dot", "vz_dot")
    train = {t: b.build(train_fl, target=t, inputs=prior.inputs(t)) for t in targets}
    test = {t: b.build(test_fl, target=t, inputs=prior.inputs(t)) for t in targets}
    r = diagnose_datasets(train, None, prior=prior, config=CFG)
    assert set(r.targets) == set(targets)
    assert "thrust_variation" in r.not_applicable and "battery_sag" in r.not_applicable
    for fe in r.final_effects:
        assert set(fe) >= {"foldable", "reason", "features"}
        for fs in fe["features"].values():
            for f in fs:
                assert f["name"].startswith(fe["effect"] + "_") and hasattr(f["expr"], "free_symbols")
    assert decisions(r) == decisions(diagnose_datasets(train, test, prior=prior, config=CFG))


def test_diagnose_and_identify_share_the_plan_on_square_run1():
    """Issue 40.1: identify reads square_run1's motor speeds late by an offset the block test
    accepts; diagnose ran without it ("effects added: none", v̇z residual twice identify's).
    Now both make one plan: the same prior, the same offset, the same effects."""
    from droneid.identify.pipeline import IdentifyConfig, plan_identification
    train = _flights(["square_run1.csv"])
    plan = plan_identification(train, IdentifyConfig.make(prior="auto"))
    res = diagnose(train, None, prior="auto", config=CFG)
    assert plan.offset is not None and plan.offset.offset_s > 0, plan.notes
    assert res.plan["prior_used"] == plan.prior.name
    assert res.plan["offset"]["offset_s"] == plan.offset.offset_s
    assert res.plan["delays_s"] == plan.delays_s
    assert res.effects_added == plan.diagnosis["effects_added"]
