"""Per-motor thrust (priors/effect_catalogue/motor_thrust): a simulated weak motor is named with
its ratio; healthy motors are not; the decision is the one rule of droneid.fitting.decide."""
from __future__ import annotations

import pytest

from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose
from droneid.simulation.simulator import simulate
from priors.effect_catalogue.motor_thrust import ratios_from_means

CFG = DiagnoseConfig(generations=0)


def test_ratio_is_relative_to_the_others():
    # equal thrusts: k_i ∝ 1/mean(ω_i²); motor 2 needs 1/0.85 of the others' ω² -> 85 %
    r = ratios_from_means([1.0, 1.0 / 0.85, 1.0, 1.0])
    assert r == pytest.approx([1.0, 0.85, 1.0, 1.0])


@pytest.mark.slow
@pytest.mark.parametrize("motor,path", [(2, "square"), (4, "random")])
def test_weak_motor_is_named_with_its_ratio(motor, path):
    sim = simulate(path=path, duration_s=40.0, seed=3, effects={"weak_motor": {"motor": motor, "gain": 0.85}})
    r = diagnose([sim.flight], prior="auto", config=CFG)
    assert "motor_thrust" in r.effects_added
    step = next(s for s in r.steps if s["effect"] == "motor_thrust")
    v = step["physical_values"]
    assert v["named_motors"] == [motor]
    assert abs(v[f"motor{motor}_ratio"] - 0.85) <= 0.05
    assert f"motor {motor} gives" in step["physical"] and "check its propeller" in step["physical"]
    assert step["evidence"]["passed"] and step["evidence"]["p_value"] < step["evidence"]["p_threshold"]
    fe = next(f for f in r.final_effects if f["effect"] == "motor_thrust")
    assert fe["foldable"] and fe["physical_values"]["named_motors"] == [motor]
    assert any("rpm2" in str(f["expr"]) for fs in fe["features"].values() for f in fs)


@pytest.mark.slow
def test_healthy_motors_are_not_named():
    for seed in (1, 2):
        sim = simulate(path="random", duration_s=40.0, seed=seed)
        r = diagnose([sim.flight], prior="auto", config=CFG)
        assert "motor_thrust" not in r.effects_added
        ev = next(c for c in r.candidates if c.get("assessed") == "motor_thrust")["scores"][0]
        assert not ev["passed"] and "motor_thrust" in ev["text"]


def test_not_applicable_without_motor_speeds():
    sim = simulate(path="square", duration_s=20.0, seed=1)
    fl = sim.flight.without("rpm1", "rpm2", "rpm3", "rpm4")
    r = diagnose([fl], prior="auto", config=CFG)
    assert "motor_thrust" in r.not_applicable
