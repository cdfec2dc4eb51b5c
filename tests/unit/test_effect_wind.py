"""The wind effect and its refine hook: the per-flight offset over k_D sets the air velocity
that drag effects act on; the diagnosis calls the hook for any effect that has one, by no name."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import diag_synth as S
from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose_datasets
from priors.effects import CATALOGUE, EffectContext

WIND = CATALOGUE["wind"]
BASE = {"k_D": {"vx_dot": 0.25, "vy_dot": 0.5}}


def _two_flights(target="vx_dot"):
    ds = S.make(None, seed=0)[target]
    flight = (np.arange(ds.t.size) >= ds.t.size // 2).astype(int)
    tilt = sum(f.expr for f in S.TiltDragStub().features(target)[:2])
    return EffectContext.build(target, ds.columns(), ds.t, flight, tilt)


def test_the_offset_over_k_d_is_the_wind_of_its_flight_only():
    ctx = _two_flights()
    c = ctx.columns
    cols = WIND.refine(ctx, {0: {"offset_x": 0.5, "offset_y": -0.25}, 1: {}}, BASE)
    first = ctx.flight == 0
    # w = offset / k_D: (0.5 / 0.25, -0.25 / 0.5) = (2, -0.5) m/s on flight 0, none on flight 1
    np.testing.assert_allclose(cols["vx_air"], np.where(first, c["vx"] - 2.0, c["vx"]))
    np.testing.assert_allclose(cols["vy_air"], np.where(first, c["vy"] + 0.5, c["vy"]))
    np.testing.assert_allclose(cols["speed_air"], np.hypot(cols["vx_air"], cols["vy_air"]))


@pytest.mark.parametrize("k_d", [{}, {"vx_dot": None, "vy_dot": None}, {"vx_dot": 1e-7, "vy_dot": 0.0}])
def test_no_positive_linear_drag_means_no_wind(k_d):
    ctx = _two_flights()
    cols = WIND.refine(ctx, {0: {"offset_x": 0.5, "offset_y": 0.5}, 1: {}}, {"k_D": k_d})
    np.testing.assert_array_equal(cols["vx_air"], ctx.columns["vx"])
    np.testing.assert_array_equal(cols["vy_air"], ctx.columns["vy"])


def test_the_wind_is_a_newton_step_when_drag_effects_read_the_air_velocity():
    """With a drag effect acting on v − ŵ the offset measures K·w + A·(w − ŵ₀), not K·w: offset / k_D
    alone diverged (case 17 of bench_diagnose: 2.35, 2.83 m/s for a wind of 1.34, 1.15, which an
    attitude delay then stood in for). The hook solves (K + A) ŵ = offset + A ŵ₀."""
    ctx = _two_flights()
    c = ctx.columns
    prev = ctx.with_columns({"vx_air": c["vx"] - 1.0, "vy_air": c["vy"] - 0.5})      # ŵ₀ = (1, 0.5)
    A = np.array([[0.6, 0.1], [0.1, 0.4]])
    off = {"offset_x": 0.5, "offset_y": -0.25}
    cols = WIND.refine(prev, {0: off, 1: {}}, {**BASE, "air_jacobian": {0: A}})
    want = np.linalg.solve(np.diag([0.25, 0.5]) + A, np.array([0.5, -0.25]) + A @ [1.0, 0.5])
    first = ctx.flight == 0
    np.testing.assert_allclose(cols["vx_air"], np.where(first, c["vx"] - want[0], c["vx"]))
    np.testing.assert_allclose(cols["vy_air"], np.where(first, c["vy"] - want[1], c["vy"]))
    # the truth is its fixed point: offset = K·w at ŵ₀ = w, whatever A
    w = np.array([1.2, -0.7])
    at = ctx.with_columns({"vx_air": c["vx"] - w[0], "vy_air": c["vy"] - w[1]})
    cols = WIND.refine(at, {0: {"offset_x": 0.25 * w[0], "offset_y": 0.5 * w[1]}, 1: {}},
                       {**BASE, "air_jacobian": {0: A}})
    np.testing.assert_allclose(cols["vx_air"][first], c["vx"][first] - w[0])
    # A = 0 is the plain rule
    cols = WIND.refine(prev, {0: off, 1: {}}, {**BASE, "air_jacobian": {0: np.zeros((2, 2))}})
    np.testing.assert_allclose(cols["vx_air"], np.where(first, c["vx"] - 2.0, c["vx"]))


def test_without_both_velocities_there_is_no_air_velocity():
    ctx = _two_flights()
    cols = {k: v for k, v in ctx.columns.items() if k != "vy"}
    ctx = EffectContext.build("vx_dot", cols, ctx.t, ctx.flight, ctx.tilt)
    assert WIND.refine(ctx, {0: {"offset_x": 0.5}}, BASE) == {}


def test_drag_effects_act_on_the_air_velocity_once_refined():
    ctx = _two_flights()
    refined = ctx.with_columns(WIND.refine(ctx, {0: {"offset_x": 0.5, "offset_y": -0.25},
                                                 1: {"offset_x": -0.25, "offset_y": 0.0}}, BASE))
    c = refined.columns
    np.testing.assert_allclose(CATALOGUE["quadratic_drag"].features(refined)["c"],
                               -np.hypot(c["vx_air"], c["vy_air"]) * c["vx_air"])
    # the folded expression is over v (the wind is a condition of the flight)
    assert {s.name for s in CATALOGUE["quadratic_drag"].expressions(refined)["c"].free_symbols} == {"vx", "vy"}
    assert "vx_air" not in ctx.columns                           # the context itself is unchanged


def test_the_diagnosis_calls_the_hook_of_any_effect_that_has_one():
    calls = []

    def recording(ctx, coef, base):
        calls.append((ctx.target, coef, base))
        return WIND.refine_fn(ctx, coef, base)

    gust = dataclasses.replace(WIND, id="gust", refine_fn=recording)
    data = S.make("wind", {"wx": 1.5, "wy": -1.0}, seed=3)
    cfg = DiagnoseConfig(generations=0, max_steps=1)
    a = diagnose_datasets(data, None, prior=S.TiltDragStub(), config=dataclasses.replace(cfg, effects=("wind",)))
    b = diagnose_datasets(data, None, prior=S.TiltDragStub(), user_effects=[gust],
                          config=dataclasses.replace(cfg, effects=("gust",)))
    assert a.effects_added == ["wind"] and b.effects_added == ["gust"]
    assert a.final_effects[0]["coefficients"] == b.final_effects[0]["coefficients"]
    # two refits, each refining both targets' contexts of the one training flight: the second
    # moves the air velocity by nothing (no drag effect reads it), so the refinement stops there
    assert [t for t, _, _ in calls] == ["vx_dot", "vy_dot"] * 2
    target, coef, base = calls[-1]
    assert set(coef) == {0} and set(coef[0]) == {"offset_x", "offset_y"}
    assert base["k_D"]["vx_dot"] == pytest.approx(S.K_D, rel=0.1)
    w = (coef[0]["offset_x"] / base["k_D"]["vx_dot"], coef[0]["offset_y"] / base["k_D"]["vy_dot"])
    assert w == pytest.approx((1.5, -1.0), abs=0.15)
