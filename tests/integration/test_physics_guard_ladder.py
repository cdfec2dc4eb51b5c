"""Identify's ladder applies the physics guard (droneid.fitting.physics_guard) to evolved terms: a term in
one motor's speed is refused even where it would pass every other guard and the block test (here
the target really holds one, planted), and a folded effect keeps the sign and size its own test
supports (droneid.diagnosis.result.folded_feature)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import sympy as sp

from droneid.diagnosis.result import folded_feature
from droneid.core.expressions import symbol
from droneid.identify.pipeline import IdentifyConfig, prepare_target
from droneid.identify.ladder import final_rung
from droneid.diagnosis.diagnose import plan_identification
from droneid.identify.search import RunRecord
from droneid.simulation.simulator import simulate
from droneid.sngp.model import SymbolicModel

CFG = IdentifyConfig.make(quick=True, effects="none", delays="none")


@pytest.fixture(scope="module")
def problem():
    train = [simulate(path="random", duration_s=30.0, rate_hz=100.0, seed=s).flight for s in (31, 32)]
    plan = plan_identification(train, CFG)
    return prepare_target(train, None, "vz_dot", CFG, plan)


def _run(p, term) -> RunRecord:
    m = SymbolicModel(tuple(p.train.input_names), [term], [1.0], 0.0, target_name=p.target)
    return RunRecord(target=p.target, model=m.to_dict())


@pytest.mark.slow
def test_a_single_motor_term_is_refused_even_when_the_data_hold_one(problem, monkeypatch):
    p = problem
    rpm2 = p.train.columns()["rpm2"]
    m, sd = float(rpm2.mean()), float(rpm2.std())
    planted = dataclasses.replace(p.train, y=p.train.y + 0.5 * (rpm2 - m) / sd)
    # without constraint samples: the planted term's offset would break "no thrust -> free fall"
    p = dataclasses.replace(p, train=planted, constraint_set=None, eval_constraint_set=None, cs_test=None)
    run = _run(p, -(symbol("rpm2") - m) / sd)
    final, guards = final_rung(p, CFG, [run])
    assert any("rpm2 but not rpm1" in d for d in guards.dropped), guards.dropped
    assert guards.chosen_run is None and not any("rpm2" in lab for lab in final.terms)
    # control: without the physics guard every other guard and the block test keep the term
    # (what identify did before), with its sign in the coefficient, never a double minus
    monkeypatch.setattr("droneid.identify.ladder.guard_terms", lambda terms, labels, *a, **k: (list(range(len(terms))), []))
    final, guards = final_rung(p, CFG, [run])
    assert guards.chosen_run == 0 and "rpm2" in list(final.terms)[-1]


def test_a_folded_effect_keeps_the_sign_and_size_its_own_test_supports():
    expr = symbol("vx") * sp.Abs(symbol("vx"))
    # judged on the motors' thrust shares: fixed at what that test measured
    motor = folded_feature("motor_thrust", {"name": "motor_thrust_w", "expr": expr, "coefficient": -6.5}, "")
    assert motor.bounds == (1.0, 1.0) and motor.expr == expr
    # judged on the v̇ residual: the diagnosed term, scaled by [0, inf)
    drag = folded_feature("quadratic_drag", {"name": "quadratic_drag_c", "expr": expr, "coefficient": -0.16}, "")
    assert drag.bounds == (0.0, np.inf)
    assert float((drag.expr / expr).evalf()) == pytest.approx(-0.16)
