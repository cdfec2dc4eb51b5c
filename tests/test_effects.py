"""The effect catalogue: features on known data, needs, interpretations, user TOML effects."""
from __future__ import annotations

import numpy as np
import pytest

import diag_synth as S
from droneid.errors import ConfigError
from priors.effects import CATALOGUE, TILT, EffectContext, load_effects, time_derivative

IDS = {"quadratic_drag", "wind", "attitude_bias", "attitude_delay", "anisotropic_drag",
       "thrust_variation", "thrust_direction", "ground_effect", "battery_sag"}


def _ctx(target="vx_dot", **drop):
    ds = S.make(None, seed=0)[target]
    tilt = sum(f.expr for f in S.TiltDragStub().features(target)[:2])
    return EffectContext.build(target, ds.columns(), ds.t, ds.flight, tilt)


def test_catalogue_has_every_documented_effect():
    assert set(CATALOGUE) == IDS
    for e in CATALOGUE.values():
        assert e.description and e.needs


def test_features_and_needs():
    ctx = _ctx()
    assert TILT in ctx.available()
    for e in CATALOGUE.values():
        cols = e.features(ctx)
        assert cols and all(np.all(np.isfinite(c)) and c.shape == ctx.t.shape for c in cols.values()), e.id
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
