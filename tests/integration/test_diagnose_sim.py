"""Diagnosis on simulated flights (droneid.simulation.simulator) with exactly ONE undeclared effect each.

Training flights are 40 s, test flights 20 s of another path, both with the same planted effect;
the open-ended search is off here (tested separately). The full pipeline runs: DatasetBuilder
(central differences on a 0.05 s grid) and priors.registry.get_prior("tilt-drag"). Tolerances are stated per effect.
"""
from __future__ import annotations

import math

import pytest

from droneid.diagnosis.diagnose import NO_FURTHER, DiagnoseConfig, diagnose
from droneid.simulation.simulator import simulate

CFG = DiagnoseConfig(generations=0)


def _diagnose(effects, train_path="square", test_path="random", seed=1, drop=(), duration_s=40.0):
    tr = simulate(path=train_path, duration_s=duration_s, seed=seed, effects=effects).flight
    te = simulate(path=test_path, duration_s=20.0, seed=seed + 10, effects=effects).flight
    if drop:
        tr, te = tr.without(*drop), te.without(*drop)
    return diagnose([tr], [te], prior="tilt-drag", config=CFG)


def _rel(a, b):
    return abs(a - b) / abs(b)


CASES = [
    # effect, params, training path, check on the physical values, tolerance statement
    ("quadratic_drag", {"c": 0.1}, "eight",
     lambda v: _rel(v["c_D_over_m_per_m"], 0.1) < 0.15),                       # c within 15 %
    ("wind", {"wx": 2.0, "wy": -1.5}, "square",
     lambda v: math.hypot(v["w_x_m_s"] - 2.0, v["w_y_m_s"] + 1.5) < 0.2 * 2.5),  # |w error| < 20 % of |w|
    ("attitude_bias", {"roll": 0.03, "pitch": -0.02}, "square",
     lambda v: abs(v["roll_bias_deg"] - math.degrees(0.03)) < 0.3
     and abs(v["pitch_bias_deg"] - math.degrees(-0.02)) < 0.3),                # within 0.3°
    ("attitude_delay", {"tau_s": 0.1}, "square",
     lambda v: abs(v["delay_ms"] - 100) < 20),                                  # within 20 ms
    ("anisotropic_drag", {"kx": 0.15, "ky": 0.45, "kz": 0.28}, "eight",
     lambda v: _rel(v["k_x_per_s"], 0.15) < 0.15 and _rel(v["k_y_per_s"], 0.45) < 0.15),
    ("thrust_variation", {"amp_m": 0.5, "period_s": 4.0}, "eight",
     lambda v: abs(v["gain"] - 1.0) < 0.2),                                     # gain 1 ± 0.2
]


def _fast_only(cases, fast):
    """``cases`` as parameters, those whose first item is not in ``fast`` marked slow: `make
    test-fast` keeps one representative of each family, `make test` runs them all."""
    return [pytest.param(*c, id=str(c[0]), marks=() if c[0] in fast else pytest.mark.slow) for c in cases]


@pytest.mark.parametrize("effect,params,path,check",
                         _fast_only(CASES, ("quadratic_drag", "wind", "thrust_variation")))
def test_simulated_effect_is_named_first_and_cuts_test_error(effect, params, path, check):
    r = _diagnose({effect: params}, train_path=path)
    assert r.effects_added[:1] == [effect], r.candidates
    step = r.steps[0]
    assert check(step["physical_values"]), step["physical"]
    for t, v in r.targets.items():
        assert v["rmse_after"]["test"] < v["rmse_before"]["test"], t
    assert r.effects_added == [effect]


@pytest.mark.parametrize("path,seed", _fast_only([("eight", 3), ("square", 4), ("random", 5), ("lissajous", 6)],
                                                  ("eight",)))
def test_simulated_control_adds_nothing(path, seed):
    r = _diagnose(None, train_path=path, seed=seed)
    assert r.effects_added == [], r.steps
    assert r.conclusion == NO_FURTHER


@pytest.mark.slow
def test_effect_without_its_signal_is_untestable():
    # battery sag planted, but the log has no voltage: untestable, never "absent"
    r = _diagnose({"battery_sag": None}, train_path="eight", drop=("battery_voltage",))
    assert "battery_sag" in r.untestable and "battery_voltage" in r.untestable["battery_sag"]
    assert "battery_sag" not in r.not_detected and r.effects_added == []
    # ground effect planted, no height in the log
    r = _diagnose({"ground_effect": None}, train_path="eight", drop=("z",))
    assert "ground_effect" in r.untestable and r.effects_added == []


@pytest.mark.slow
def test_effect_invisible_in_horizontal_dynamics_is_not_detected():
    # an altitude-holding controller balances the battery's thrust loss: nothing to see in v̇x, v̇y
    r = _diagnose({"battery_sag": None}, train_path="eight")
    assert r.effects_added == [] and "battery_sag" in r.not_detected


@pytest.mark.slow
@pytest.mark.parametrize("c", [0.15, 0.3])
def test_wind_is_per_flight_and_quadratic_drag_acts_on_air_velocity(c):
    """Training flight with wind AND quadratic drag; the test flight has a different wind. At
    c = 0.3 1/m the quadratic drag's slope outweighs the linear drag (0.28 1/s) and the wind read
    as offset / k_D diverged (train (1.86, −1.34), test (0.17, −0.10) m/s, c 0.38): the wind is a
    Newton step that takes the drag effects' own slope in the wind (the air Jacobian)."""
    eff = {"wind": {"wx": 1.5, "wy": -1.0}, "quadratic_drag": {"c": c}}
    tr = simulate(path="random", duration_s=40.0, seed=1, effects=eff).flight
    te = simulate(path="square", duration_s=20.0, seed=11,
                  effects={"wind": {"wx": -0.5, "wy": 1.0}, "quadratic_drag": {"c": c}}).flight
    r = diagnose([tr], [te], config=CFG)
    assert r.effects_added == ["wind", "quadratic_drag"]
    fin = {f["effect"]: f for f in r.final_effects}
    assert _rel(fin["quadratic_drag"]["physical_values"]["c_D_over_m_per_m"], c) < 0.05
    per = fin["wind"]["physical_per_flight"]
    (trw,) = [v for k, v in per.items() if k.startswith("train:")]
    (tew,) = [v for k, v in per.items() if k.startswith("test:")]
    assert math.hypot(trw["w_x_m_s"] - 1.5, trw["w_y_m_s"] + 1.0) < 0.1
    assert math.hypot(tew["w_x_m_s"] + 0.5, tew["w_y_m_s"] - 1.0) < 0.1
    for v in r.targets.values():
        assert v["rmse_after"]["test"] < 0.5 * v["rmse_before"]["test"]


# -- the same flights with the prior identify uses by default (rotor-thrust from the motor commands)
AUTO_CASES = [c for c in CASES if c[0] in ("wind", "attitude_bias", "attitude_delay", "quadratic_drag")]


@pytest.mark.parametrize("effect,params,path,check", _fast_only(AUTO_CASES, ("attitude_bias",)))
def test_rotor_thrust_prior_names_the_planted_effect(effect, params, path, check):
    tr = simulate(path=path, duration_s=40.0, seed=1, effects={effect: params}).flight
    r = diagnose([tr], None, prior="auto", config=CFG)
    assert r.prior.startswith("rotor-thrust") and "vz_dot" in r.targets
    assert r.effects_added == [effect], r.candidates
    # values read relative to the FITTED thrust, so they match the planted ones as with tilt-drag
    assert check(r.steps[0]["physical_values"]), r.steps[0]["physical"]
    assert "thrust_variation" in r.not_applicable


@pytest.mark.parametrize("path,seed", _fast_only([("eight", 3), ("square", 4)], ()))
def test_rotor_thrust_control_adds_nothing_and_flat_heights_leave_ground_effect_untestable(path, seed):
    tr = simulate(path=path, duration_s=40.0, seed=seed).flight
    r = diagnose([tr], None, prior="auto", config=CFG)
    assert r.effects_added == [], r.candidates
    assert "no time near the ground" in r.untestable["ground_effect"]
