"""The effect catalogue: invariants every registered effect keeps, features on known data, needs,
interpretations, user TOML effects. No id list is pinned here: a built-in effect is one module of
priors/effect_catalogue/ (tests/unit/test_effect_catalogue.py checks the discovery)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import diag_synth as S
from droneid.errors import ConfigError
from droneid.core.targets import TARGETS
from priors.effects import CATALOGUE, TILT, Effect, EffectContext, Interpretation, load_effects, \
    time_derivative
from priors.registry import get_prior

ROTOR = get_prior("rotor-thrust", source="rpm", motors=4)
BASE = {"k_D": {"vx_dot": 0.28, "vy_dot": 0.28, "vz_dot": 0.3}}
UNIT_TESTS = Path(__file__).parent


def _ctx(target="vx_dot", **drop):
    ds = S.make(None, seed=0)[target]
    tilt = sum(f.expr for f in S.TiltDragStub().features(target)[:2])
    return EffectContext.build(target, ds.columns(), ds.t, ds.flight, tilt)


def _rotor_ctx(target):
    ds = S.make_rotor(None, seed=0)[target]
    g = sum(f.expr for f in ROTOR.features(target) if f.role == "thrust")
    return EffectContext.build(target, ds.columns(), ds.t, ds.flight, g, tilt_role="thrust")


def _standard():
    """(label, Dataset, EffectContext) on which every effect's invariants are checked: the
    tilt-drag synthetic flight (v̇x, v̇y) and the rotor-thrust one from motor speeds (v̇x, v̇y, v̇z)."""
    out = []
    for tgt in ("vx_dot", "vy_dot"):
        out.append((f"tilt-drag {tgt}", S.make(None, seed=0)[tgt], _ctx(tgt)))
    for tgt in ("vx_dot", "vy_dot", "vz_dot"):
        out.append((f"rotor-thrust {tgt}", S.make_rotor(None, seed=0)[tgt], _rotor_ctx(tgt)))
    return out


@pytest.fixture(scope="module")
def standard():
    return _standard()


# -- invariants of every registered effect ------------------------------------------------------
@pytest.mark.parametrize("eid", list(CATALOGUE))
def test_every_effect_is_well_formed(eid):
    e = CATALOGUE[eid]
    assert isinstance(e, Effect) and e.id == eid and eid.isidentifier() and not e.user
    assert e.description and e.needs and all(grp and all(isinstance(a, str) for a in grp) for grp in e.needs)
    assert e.targets and set(e.targets) <= set(TARGETS), e.targets
    assert (e.expr_fn is None) != (e.column_fn is None), "exactly one of expr_fn, column_fn"
    assert e.foldable == (e.expr_fn is not None and not e.per_flight and not e.fold_reason)
    assert e.foldable or e.fold_reason, "a non-foldable effect says why (fold_reason)"
    assert not (e.per_flight and e.foldable)


@pytest.mark.parametrize("eid", list(CATALOGUE))
def test_every_effect_is_exercised_by_a_standard_context_or_its_own_test(eid, standard):
    e = CATALOGUE[eid]
    applies = [label for label, _, ctx in standard if e.features(ctx)]
    assert applies or (UNIT_TESTS / f"test_effect_{eid}.py").is_file(), (
        f"{eid} has features on none of the standard contexts: test it in tests/unit/test_effect_{eid}.py")


@pytest.mark.parametrize("eid", list(CATALOGUE))
def test_every_effect_interprets_its_own_parameters(eid, standard):
    e = CATALOGUE[eid]
    for label, _, ctx in standard:
        params = e.features(ctx)
        if not params:
            continue
        it = e.interpret({k: 0.1 for k in params}, BASE)
        assert isinstance(it, Interpretation) and isinstance(it.text, str) and it.text, (eid, label)
        assert it.values and all(isinstance(v, float) and math.isfinite(v) for v in it.values.values()), \
            (eid, label, it.values)


@pytest.mark.parametrize("eid", [e.id for e in CATALOGUE.values() if e.refine_fn is not None])
def test_every_refine_hook_adds_finite_columns_and_never_overwrites_data(eid, standard):
    e = CATALOGUE[eid]
    for label, _, ctx in standard:
        flights = np.unique(ctx.flight)
        for coef in ({int(f): {} for f in flights},
                     {int(f): {k: 0.1 for k in e.features(ctx)} for f in flights}):
            cols = e.refine(ctx, coef, BASE)
            for k, v in cols.items():
                assert k not in ctx.columns, (eid, label, k)      # a derived column, never a signal
                assert v.shape == ctx.t.shape and np.all(np.isfinite(v)), (eid, label, k)


def test_effects_without_a_refine_hook_refine_nothing():
    ctx = _ctx()
    for e in CATALOGUE.values():
        if e.refine_fn is None:
            assert e.refine(ctx, {0: {}}, BASE) == {}, e.id


def test_features_and_needs(standard):
    for label, _, ctx in standard:
        assert TILT in ctx.available()
        for e in CATALOGUE.values():
            cols = e.features(ctx)
            if e.not_applicable(ctx) or e.missing(ctx.available()):
                assert cols == {}, (e.id, label)
                continue
            assert cols and all(np.all(np.isfinite(c)) and c.shape == ctx.t.shape
                                for c in cols.values()), (e.id, label)
    ctx = _ctx()
    c = ctx.columns
    np.testing.assert_allclose(CATALOGUE["quadratic_drag"].features(ctx)["c"],
                               -np.hypot(c["vx"], c["vy"]) * c["vx"])
    assert CATALOGUE["battery_sag"].missing({TILT, "throttle"}) == ["battery_voltage"]
    assert CATALOGUE["ground_effect"].missing({"vx"}) == ["thrust-direction (tilt or thrust) terms of the prior", "z"]


def test_attitude_bias_feature_is_the_derivative_of_the_tilt_terms():
    ctx = _ctx()
    c = ctx.columns
    d = 1e-6
    gx1, _ = S.tilt(c["roll"], c["pitch"] + d, c["yaw"])
    gx0, _ = S.tilt(c["roll"], c["pitch"] - d, c["yaw"])
    np.testing.assert_allclose(CATALOGUE["attitude_bias"].features(ctx)["d_pitch"], (gx1 - gx0) / (2 * d),
                               rtol=1e-5, atol=1e-6)


def test_anisotropic_drag_feature_matches_body_frame_drag():
    ctx = _ctx("vy_dot")
    c = ctx.columns
    psi, vx, vy = c["yaw"], c["vx"], c["vy"]
    u, w = np.cos(psi) * vx + np.sin(psi) * vy, -np.sin(psi) * vx + np.cos(psi) * vy
    kx, ky = 0.4, 0.2
    ay = -np.sin(psi) * kx * u - np.cos(psi) * ky * w
    f = CATALOGUE["anisotropic_drag"].features(ctx)["dk"]
    np.testing.assert_allclose(ay, -0.3 * vy + (kx - ky) * f, atol=1e-12)


def test_time_derivative_respects_flight_boundaries_and_gaps():
    t = np.r_[np.arange(0, 1, 0.1), np.arange(5, 6, 0.1)]
    f = np.zeros(t.size, int)
    x = 2.0 * t
    np.testing.assert_allclose(time_derivative(x, t, f), 2.0)


def test_interpretations():
    base = {"k_D": {"vx_dot": 0.25, "vy_dot": 0.25}}
    assert "wind ≈ (2, -1) m/s" == CATALOGUE["wind"].interpret({"offset_x": 0.5, "offset_y": -0.25}, base).text
    assert "lags acceleration by 50 ms" in CATALOGUE["attitude_delay"].interpret({"tau": 0.05}, base).text
    txt = CATALOGUE["attitude_bias"].interpret({"d_roll": 0.0, "d_pitch": np.radians(2.0)}, base).text
    assert "pitch bias -2.00°" in txt
    assert "c_D/m = 0.12 1/m" in CATALOGUE["quadratic_drag"].interpret({"c": 0.12}, base).text


def test_user_effect_from_toml(tmp_path):
    p = tmp_path / "fx.toml"
    p.write_text('''
[[effect]]
id = "cubic_drag"
description = "drag growing with v cubed"
meaning = "cubic drag k3 = {k3:.3g}"
[effect.features.vx_dot]
k3 = "-vx**3"
[effect.features.vy_dot]
k3 = "-vy^3"
''')
    fx = load_effects(p)
    e = fx["cubic_drag"]
    ctx = _ctx()
    np.testing.assert_allclose(e.features(ctx)["k3"], -ctx.columns["vx"] ** 3)
    assert e.interpret({"k3": 0.5}, {}).text == "cubic drag k3 = 0.5"


@pytest.mark.parametrize("body,match", [
    ('[[effect]]\nid = "a"\n[effect.features.vx_dot]\nk = "__import__(1)"', "not allowed"),
    ('[[effect]]\nid = "a"\n[effect.features.vx_dot]\nk = "vxx"', "did you mean 'vx'"),
    ('[[effect]]\nid = "a"\nmeaning = "{q}"\n[effect.features.vx_dot]\nk = "vx"', "unknown name 'q'"),
    ('[[effect]]\nid = "wind"\n[effect.features.vx_dot]\nk = "vx"', "built-in"),
    ('[[effect]]\nid = "a"\n[effect.features.v_dot]\nk = "vx"', "unknown target"),
    ('[[effect]]\nid = "a"\nfeature = 1', "unknown key 'feature'"),
    ('effect = [', "not valid TOML"),
])
def test_user_effect_errors(tmp_path, body, match):
    p = tmp_path / "bad.toml"
    p.write_text(body)
    with pytest.raises(ConfigError, match=match):
        load_effects(p)


# -- foldable effects: expressions over canonical signals reproduce the fitted columns ------------
from droneid.core.expressions import compile_expression  # noqa: E402
from priors.effects import is_measured_derivative, thrust_proxy  # noqa: E402


def _eval_on_dataset(expr, ds):
    cols = ds.columns()
    names = sorted(s.name for s in expr.free_symbols)
    assert set(names) <= set(cols), (expr, set(names) - set(cols))   # canonical signals only
    return compile_expression(expr, names)({k: cols[k] for k in names})


@pytest.mark.parametrize("which", range(5))
def test_every_foldable_effect_expression_reproduces_its_feature_column(which):
    label, ds, ctx = _standard()[which]
    for e in CATALOGUE.values():
        consts = e.constants(ctx)
        exprs = e.expressions(ctx, consts)
        if not e.applies_to(ctx.target) or e.not_applicable(ctx):
            assert exprs == {} and e.features(ctx) == {}, (e.id, label)
            continue
        if not e.foldable:
            assert exprs == {} and e.fold_reason, (e.id, label)
            continue
        cols = e.features(ctx, consts)
        assert exprs and set(exprs) == set(cols), (e.id, label)
        for k, expr in exprs.items():
            assert all(not is_measured_derivative(s.name) for s in expr.free_symbols), (e.id, expr)
            diff = np.max(np.abs(_eval_on_dataset(expr, ds) - cols[k]))
            assert diff < 1e-9, (e.id, label, k, diff)


def test_rotor_thrust_vz_expressions_reproduce_columns_and_skip_horizontal_only_effects():
    ds = S.make_rotor(None, seed=0)["vz_dot"]
    ctx = _rotor_ctx("vz_dot")
    for eid in ("vertical_drag", "ground_effect", "thrust_curve"):
        e = CATALOGUE[eid]
        exprs = e.expressions(ctx)
        assert exprs, eid
        for k, col in e.features(ctx).items():
            assert np.max(np.abs(_eval_on_dataset(exprs[k], ds) - col)) < 1e-9, (eid, k)
    assert set(CATALOGUE["vertical_drag"].expressions(ctx)) == {"c_z"}
    for eid in ("quadratic_drag", "wind", "anisotropic_drag", "thrust_direction", "thrust_variation"):
        assert CATALOGUE[eid].not_applicable(ctx), eid
    assert "measured rotor speeds" in CATALOGUE["battery_sag"].not_applicable(ctx)


def test_thrust_variation_is_built_from_the_logged_thrust_never_from_a_derivative():
    ctx = _ctx()
    assert "vz_dot" not in ctx.columns                   # a measured derivative: absent by default
    e = CATALOGUE["thrust_variation"]
    k = e.constants(ctx)
    c = ctx.columns
    assert k["T_mean"] == pytest.approx(np.mean(c["throttle"]))       # training mean of the proxy
    np.testing.assert_allclose(e.features(ctx)["s"], c["G"] * (c["throttle"] / k["T_mean"] - 1),
                               atol=1e-12)
    assert "vz" not in {s.name for s in e.expressions(ctx)["s"].free_symbols}
    assert thrust_proxy({"throttle", "rpm1", "rpm2"})[0] == "Σ(rpm/10⁴)²"
    assert thrust_proxy({"throttle", "thrust"})[0] == "thrust"
    assert thrust_proxy({"vx"}) is None
    # a motor missing below the highest: the motors that are there are no collective thrust
    # (a walkthrough found rpm1 + rpm2 summed for rpm1, rpm2, rpm4)
    assert thrust_proxy({"rpm1", "rpm2", "rpm4", "motor1", "motor2", "motor3", "motor4"})[0] == "mean motor command"
    assert thrust_proxy({"rpm1", "rpm2", "rpm4", "throttle"})[0] == "throttle"
    assert e.missing({TILT, "vz", "az"}) == ["thrust|rpm1|motor1|throttle"]
    # with the rotor-thrust prior the thrust IS logged: not applicable
    thr = EffectContext.build("vx_dot", ctx.columns, ctx.t, ctx.flight, ctx.tilt, tilt_role="thrust")
    assert "rotor-thrust" in e.not_applicable(thr) and e.features(thr) == {}


def test_measured_derivatives_only_with_the_explicit_option():
    ds = S.make(None, seed=0)["vx_dot"]
    cols = {**ds.columns(), "az": np.full(len(ds), 9.8), "ax": np.zeros(len(ds))}
    tilt = sum(f.expr for f in S.TiltDragStub().features("vx_dot")[:2])
    ctx = EffectContext.build("vx_dot", cols, ds.t, ds.flight, tilt)
    assert not {"az", "ax", "vz_dot"} & set(ctx.columns)
    ctx = EffectContext.build("vx_dot", cols, ds.t, ds.flight, tilt, allow_measured_derivatives=True)
    assert {"az", "ax", "vz_dot"} <= set(ctx.columns)


def test_user_effect_expression_substitutes_derived_names_and_flags_derivatives(tmp_path):
    p = tmp_path / "fx.toml"
    p.write_text('''
[[effect]]
id = "speed_tilt"
[effect.features.vx_dot]
k = "G * speed"
[[effect]]
id = "climb"
[effect.features.vx_dot]
k = "G * vz_dot"
''')
    fx = load_effects(p)
    ds = S.make(None, seed=0)["vx_dot"]
    ctx = _ctx()
    e = fx["speed_tilt"]
    assert e.foldable and e.targets == ("vx_dot",)
    (expr,) = e.expressions(ctx).values()
    assert {s.name for s in expr.free_symbols} <= {"vx", "vy", "roll", "pitch", "yaw"}
    np.testing.assert_allclose(_eval_on_dataset(expr, ds), e.features(ctx)["k"], atol=1e-9)
    c = fx["climb"]
    assert not c.foldable and "measured derivative" in c.fold_reason
    assert c.missing(ctx.available()) == ["vz_dot"]          # untestable without the option


def test_attitude_rate_is_the_terms_change_per_second_of_attitude_alignment():
    """The lead's column (droneid.identify.ladder.per_flight_condition_lead): the terms read at
    the attitude τ later change by τ times it, the thrust magnitude held (its timing is the
    thrust offset's), yaw read across its ±π wrap without a jump, None without an angle."""
    from droneid.core.expressions import symbol
    import sympy as sp
    from priors.effect_catalogue.attitude_delay import attitude_rate
    t = np.arange(0.0, 4.0, 0.01)
    pitch, yaw = 0.3 * np.sin(2.0 * t), np.angle(np.exp(1j * (3.0 + 1.5 * t)))   # yaw wraps at +π
    thrust = 9.0 + np.sin(5.0 * t)
    cols = {"pitch": pitch, "yaw": yaw, "S": thrust}
    P, Y, S = symbol("pitch"), symbol("yaw"), symbol("S")
    flight = np.zeros(t.size, int)
    got = attitude_rate([sp.sin(P) * sp.cos(Y) * S], cols, t, flight, half_window_s=0.02)
    want = (np.cos(pitch) * 0.6 * np.cos(2.0 * t) * np.cos(yaw) - np.sin(pitch) * np.sin(yaw) * 1.5) * thrust
    inner = slice(5, -5)
    assert np.max(np.abs(got[inner] - want[inner])) < 0.01 * np.max(np.abs(want))
    assert attitude_rate([S * 2.0], cols, t, flight) is None
    # weighted by the terms' fitted coefficients, so that its own coefficient is τ itself
    two = attitude_rate([sp.sin(P) * sp.cos(Y) * S, 0.5 * sp.sin(P) * S], cols, t, flight, half_window_s=0.02,
                        weights=[0.9, 2.0])
    want2 = 0.9 * want + 2.0 * 0.5 * np.cos(pitch) * 0.6 * np.cos(2.0 * t) * thrust
    assert np.max(np.abs(two[inner] - want2[inner])) < 0.01 * np.max(np.abs(want2))
    # a missing sample leaves its neighbourhood NaN, the rest of the flight (yaw's unwrap too) intact
    gap = {**cols, "yaw": np.where(np.arange(t.size) == 200, np.nan, yaw)}
    holed = attitude_rate([sp.sin(P) * sp.cos(Y) * S], gap, t, flight, half_window_s=0.02)
    ok = np.isfinite(holed)
    assert 0 < np.sum(~ok) < 10 and np.max(np.abs(holed[inner][ok[inner]] - want[inner][ok[inner]])) \
        < 0.01 * np.max(np.abs(want))
