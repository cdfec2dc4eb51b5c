"""Diagnosis decisions use the training flights only; causal inputs; pairs of overlapping
effects; rotor-thrust priors with v̇z; effects folded as expressions."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import diag_synth as S
from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose_datasets
from droneid.core.expressions import compile_expression
from priors.effects import Effect, Interpretation, load_effects
from priors.registry import get_prior

CFG = DiagnoseConfig(generations=0)
ROTOR = get_prior("rotor-thrust", source="rpm", motors=4)


@pytest.mark.parametrize("effect,params", [("quadratic_drag", {"c": 0.1}), (None, {}),
                                           ("attitude_delay", {"tau_s": 0.05})])
def test_same_model_with_and_without_test_flights(effect, params):
    train = S.make(effect, params, seed=4)
    test = S.make(effect, params, seed=104, phase=1.0)
    a = diagnose_datasets(train, None, prior=S.TiltDragStub(), config=CFG)
    b = diagnose_datasets(train, test, prior=S.TiltDragStub(), config=CFG)
    assert S.decisions(a) == S.decisions(b)
    assert a.targets["vx_dot"]["rmse_after"]["test"] is None
    assert b.targets["vx_dot"]["rmse_after"]["test"] is not None        # test errors are reported
    if effect:
        assert a.effects_added == [effect]


def test_a_test_flight_that_gets_worse_does_not_veto_the_effect():
    # the test flight has NO quadratic drag: adding it makes the test worse, yet training decides
    train = S.make("quadratic_drag", {"c": 0.1}, seed=5)
    test = S.make(None, seed=105, phase=1.0)
    r = diagnose_datasets(train, test, prior=S.TiltDragStub(), config=CFG)
    assert r.effects_added == ["quadratic_drag"]
    ev = r.steps[0]["evidence"]
    assert ev["test_rmse_after"] > ev["test_rmse_before"] and ev["passed"]


def test_test_flights_lacking_a_signal_change_nothing_but_the_test_report():
    train = S.make(None, seed=6)
    test = S.make(None, seed=106, phase=1.0, drop=("z", "battery_voltage", "throttle"))
    a = diagnose_datasets(train, None, prior=S.TiltDragStub(), config=CFG)
    b = diagnose_datasets(train, test, prior=S.TiltDragStub(), config=CFG)
    # the synthetic flight stays 1.2-2.8 m high: ground effect is untestable (no time near the
    # ground), on the training flights alone, with or without the test flights
    assert S.decisions(a) == S.decisions(b) and "ground_effect" in b.untestable


# -- overlapping effects --------------------------------------------------------------------------
def _u(ctx):
    return np.sin(1.3 * ctx.t)


def _w(ctx):
    """Strong, but only in the last quarter of each flight (a few CV blocks)."""
    out = np.zeros(ctx.t.size)
    for f in np.unique(ctx.flight):
        m = ctx.flight == f
        on = m & (ctx.t >= np.quantile(ctx.t[m], 3 / 4))
        out[on] = 6.0 * np.sin(0.7 * ctx.t[on])
    return out


def _overlap_effects():
    def text(coef, base):
        return Interpretation(str(coef), dict(coef))
    # truth 2u = A + B with A = u + w, B = u − w: either alone fits u well but adds w where it
    # is strong (one block much worse), so neither passes the block test; the pair is exact
    a = Effect("over_a", "u + w", (("vx",),), text, column_fn=lambda ctx, k: {"a": _u(ctx) + _w(ctx)})
    b = Effect("over_b", "u − w", (("vx",),), text, column_fn=lambda ctx, k: {"b": _u(ctx) - _w(ctx)})
    return [a, b]


def _plant_overlap(data):
    out = {}
    for t, ds in data.items():
        out[t] = dataclasses.replace(ds, y=ds.y + 2 * _u(ds))
    return out


def test_overlapping_effects_are_found_by_testing_pairs_jointly():
    data = _plant_overlap(S.make(None, seed=7))
    cfg = DiagnoseConfig(generations=0, effects=("over_a", "over_b", "quadratic_drag", "wind"))
    r = diagnose_datasets(data, None, prior=S.TiltDragStub(), config=cfg, user_effects=_overlap_effects())
    first = r.candidates[0]
    # each alone gains a lot but fails the block test ...
    best = first["scores"][0]
    assert best["effect"] in ("over_a", "over_b") and not best["passed"] and best["rel_improvement"] > 0.05
    # ... so pairs were tested jointly with the threshold adjusted for singles + pairs
    assert "tested jointly" in first["pairs_reason"]
    pair = first["pairs"][0]
    assert sorted(pair["effects"]) == ["over_a", "over_b"] and pair["passed"]
    assert pair["p_threshold"] < 0.01 / 4
    assert sorted(r.effects_added[:2]) == ["over_a", "over_b"]
    assert sorted(r.steps[0]["tested_jointly"]) == ["over_a", "over_b"]
    assert "quadratic_drag" not in r.effects_added and "wind" not in r.effects_added


def test_pairs_make_no_false_discovery_on_controls():
    for seed in (20, 21, 22):
        r = diagnose_datasets(S.make(None, seed=seed), None, prior=S.TiltDragStub(),
                              config=DiagnoseConfig(generations=0, pair_min_gain=0.0))
        assert r.effects_added == [], (seed, r.candidates)


# -- causal inputs ------------------------------------------------------------------------------
def _plant_vz_dot_term(data, gain=20.0):
    out = {}
    for t, ds in data.items():
        c = ds.columns()
        gx, gy = S.tilt(c["roll"], c["pitch"], c["yaw"])
        vz_dot = 0.2 * np.cos(0.5 * ds.t)       # d/dt of diag_synth's vz
        out[t] = dataclasses.replace(ds, y=ds.y + gain * (gx if t == "vx_dot" else gy) * vz_dot / S.G)
    return out


def test_an_effect_needing_a_measured_derivative_is_untestable_unless_allowed(tmp_path):
    p = tmp_path / "fx.toml"
    p.write_text('[[effect]]\nid = "climb"\n[effect.features.vx_dot]\ns = "G * vz_dot / g"\n'
                 '[effect.features.vy_dot]\ns = "G * vz_dot / g"\n')
    fx = load_effects(p)
    data = _plant_vz_dot_term(S.make(None, seed=8))
    r = diagnose_datasets(data, None, prior=S.TiltDragStub(), config=CFG, user_effects=fx)
    assert "climb" in r.untestable and "allow-measured-derivatives" in r.untestable["climb"]
    assert r.simulable and "climb" not in r.effects_added
    cfg = DiagnoseConfig(generations=0, allow_measured_derivatives=True)
    r = diagnose_datasets(data, None, prior=S.TiltDragStub(), config=cfg, user_effects=fx)
    assert r.effects_added[0] == "climb"
    assert not r.simulable and "cannot be simulated" in r.notes[0]
    assert "NOT simulable" in r.conclusion
    fin = {f["effect"]: f for f in r.final_effects}
    assert not fin["climb"]["foldable"] and "measured derivative" in fin["climb"]["reason"]


def test_open_ended_search_never_sees_measured_derivatives_by_default():
    data = S.make(None, seed=9, duration_s=30)
    data = {t: dataclasses.replace(ds, extra={**ds.extra, "az": np.full(len(ds), 9.81),
                                              "ax": np.sin(ds.t)}) for t, ds in data.items()}
    cfg = DiagnoseConfig(generations=20, population_size=100)
    r = diagnose_datasets(data, None, prior=S.TiltDragStub(), config=cfg)
    for o in r.open_ended.values():
        assert o["ran"] and not {"ax", "az", "vz_dot"} & set(o["signals"])
    r = diagnose_datasets(data, None, prior=S.TiltDragStub(),
                          config=dataclasses.replace(cfg, allow_measured_derivatives=True))
    assert "ax" in r.open_ended["vx_dot"]["signals"] and "vz_dot" in r.open_ended["vx_dot"]["signals"]


# -- any prior, any target: rotor-thrust with v̇z ---------------------------------------------------
def _eval(expr, ds):
    cols = ds.columns()
    names = sorted(s.name for s in expr.free_symbols)
    return compile_expression(expr, names)({k: cols[k] for k in names})


def test_rotor_thrust_quadratic_drag_with_vertical_term_is_found_and_folds():
    train = S.make_rotor("quadratic_drag", {"c": 0.1, "c_z": 1.0}, seed=1)
    test = S.make_rotor("quadratic_drag", {"c": 0.1, "c_z": 1.0}, seed=101, phase=1.0)
    r = diagnose_datasets(train, test, prior=ROTOR, config=CFG)
    assert sorted(r.effects_added) == ["quadratic_drag", "vertical_drag"]
    assert {"thrust_variation", "thrust_direction", "battery_sag"} <= set(r.not_applicable)
    fin = {f["effect"]: f for f in r.final_effects}
    fe, fv = fin["quadratic_drag"], fin["vertical_drag"]
    assert abs(fe["physical_values"]["c_D_over_m_per_m"] - 0.1) < 0.01
    assert abs(fv["physical_values"]["c_D_z_over_m_per_m"] - 1.0) < 0.1
    assert fe["foldable"] and set(fe["features"]) == {"vx_dot", "vy_dot"}
    assert fv["foldable"] and set(fv["features"]) == {"vz_dot"}
    (fz,) = fv["features"]["vz_dot"]
    assert fz["name"] == "vertical_drag_c_z"
    vz = train["vz_dot"].columns()["vz"]
    np.testing.assert_allclose(fz["coefficient"] * _eval(fz["expr"], train["vz_dot"]),
                               -1.0 * np.abs(vz) * vz, atol=0.1 * np.max(vz ** 2))
    json.dumps(r.to_dict(), allow_nan=False)
    fj = {f["effect"]: f for f in r.to_dict()["final_effects"]}
    assert isinstance(fj["vertical_drag"]["features"]["vz_dot"][0]["expr"], str)


def test_rotor_thrust_ground_effect_folds_to_the_planted_law():
    planted = {"R": 0.15}
    train = S.make_rotor("ground_effect", planted, seed=2, duration_s=120)
    r = diagnose_datasets(train, None, prior=ROTOR, config=CFG)
    assert r.effects_added == ["ground_effect"]
    (fe,) = r.final_effects
    for t, (f,) in fe["features"].items():
        ds = train[t]
        c = ds.columns()
        g = sum(p.expr for p in ROTOR.features(t) if p.role == "thrust")
        thrust_term = _eval(g, ds)
        truth = planted["R"] ** 2 / (4 * np.maximum(c["z"], 0.05)) ** 2 * thrust_term
        got = f["coefficient"] * _eval(f["expr"], ds)
        assert np.max(np.abs(got - truth)) < 0.15 * np.max(np.abs(truth)), t


@pytest.mark.parametrize("seed", [3, 4])
def test_rotor_thrust_control_adds_nothing(seed):
    r = diagnose_datasets(S.make_rotor(None, seed=seed), None, prior=ROTOR, config=CFG)
    assert r.effects_added == []


def test_an_open_ended_term_in_a_measured_derivative_makes_the_model_not_simulable():
    data = S.make(None, seed=10, duration_s=30)
    data = {t: dataclasses.replace(ds, y=ds.y + 1.5 * np.sin(1.7 * ds.t),
                                   extra={**ds.extra, "ax": np.sin(1.7 * ds.t)})
            for t, ds in data.items()}
    cfg = DiagnoseConfig(generations=300, population_size=100, allow_measured_derivatives=True,
                         effects=("quadratic_drag",))
    r = diagnose_datasets(data, None, prior=S.TiltDragStub(), config=cfg)
    o = r.open_ended["vx_dot"]
    assert o["passed"] and "ax" in o["equation"], o
    assert not r.simulable and "ax" in r.notes[0] and "NOT simulable" in r.conclusion


def test_folding_the_found_effects_into_the_prior_leaves_nothing_to_find():
    from droneid.diagnosis.diagnose import fold_into_prior
    train = S.make_rotor("quadratic_drag", {"c": 0.1, "c_z": 1.0}, seed=5)
    r = diagnose_datasets(train, None, prior=ROTOR, config=CFG)
    assert sorted(r.effects_added) == ["quadratic_drag", "vertical_drag"]
    folded = fold_into_prior(r, ROTOR)
    assert [f.name for f in folded.features("vz_dot")][-1] == "vertical_drag_c_z"
    assert "quadratic_drag_c" in [f.name for f in folded.features("vx_dot")]
    assert "vz" in folded.inputs("vz_dot") and "vy" in folded.inputs("vx_dot")
    r2 = diagnose_datasets(train, None, prior=folded, config=CFG)
    assert r2.effects_added == []
    for t in train:
        assert r2.targets[t]["rmse_before"]["cv"] <= r.targets[t]["rmse_after"]["cv"] * 1.001
