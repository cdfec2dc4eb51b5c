"""Vehicle constants across flights (droneid.fitting.constancy, terms.physical_fit with flights): the
constancy test flags a coefficient that moves between flights, keeps one that does not, has its
size on exact-noise draws, and the interval of a pooled constant covers how flights differ."""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from droneid.fitting.constancy import (ALPHA, Constancy, constancy_line, constancy_sentence, heterogeneity,
                               holm_flags, n_stretches, units_of)
from droneid.fitting.flight_conditions import explained, one_factor_per_flight
from droneid.fitting.terms import TermModel, physical_fit
from droneid.dataset.validation import time_blocks


def test_heterogeneity_of_agreeing_and_disagreeing_units():
    same = heterogeneity([1.0, 1.01, 0.99, 1.0], [0.02] * 4)
    assert same["p"] > 0.5 and same["tau"] == 0.0 and same["low"] < 1.0 < same["high"]
    apart = heterogeneity([0.2, 0.3, 1.4, 1.5], [0.02] * 4)
    assert apart["p"] < 1e-6 and apart["tau"] > 0.3
    # the between-flight interval counts the spread: it reaches well past the within-unit noise
    assert apart["high"] - apart["low"] > 1.0
    assert math.isnan(heterogeneity([1.0], [0.1])["p"])


def test_the_q_test_has_its_size_on_units_that_differ_by_their_noise_only():
    rng = np.random.default_rng(0)
    se = np.array([0.01, 0.02, 0.015, 0.03, 0.01])
    ps = np.array([heterogeneity(1.0 + se * rng.standard_normal(5), se)["p"] for _ in range(4000)])
    assert abs(np.mean(ps < 0.05) - 0.05) < 0.015
    assert np.mean(ps < ALPHA) < 0.02


def test_the_test_keeps_its_size_when_each_standard_error_is_estimated_from_ten_blocks():
    """Standard errors from ten time blocks are estimates on 9 degrees of freedom: read as known
    (Cochran's Q against χ²), five such units are called different several times as often as the
    level says; read as Welch's test, about as often as it says."""
    rng = np.random.default_rng(2)
    sigma = np.array([0.01, 0.02, 0.015, 0.03, 0.01])
    known, welch = [], []
    for _ in range(6000):
        v = 1.0 + sigma * rng.standard_normal(5)
        se = sigma * np.sqrt(rng.chisquare(9, 5) / 9)
        known.append(heterogeneity(v, se)["p"])
        welch.append(heterogeneity(v, se, [9.0] * 5)["p"])
    assert np.mean(np.array(known) < ALPHA) > 3 * ALPHA
    assert np.mean(np.array(welch) < ALPHA) < 1.6 * ALPHA
    assert abs(np.mean(np.array(welch) < 0.05) - 0.05) < 0.012


def test_random_effects_interval_covers_the_mean_of_heterogeneous_flights():
    """Flights whose constants scatter around μ with spread τ (noise se): the HKSJ interval from
    the flights covers μ in about 95 % of draws (the point of counting flight-to-flight variation)."""
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(2000):
        se = rng.uniform(0.01, 0.03, 5)
        v = 1.0 + 0.1 * rng.standard_normal(5) + se * rng.standard_normal(5)
        h = heterogeneity(v, se)
        hits += h["low"] <= 1.0 <= h["high"]
    assert hits / 2000 >= 0.93


def test_holm_flags():
    assert holm_flags({"a": 0.001, "b": 0.2}) == {"a": True, "b": False}
    assert holm_flags({"a": 0.006, "b": 0.004}) == {"a": True, "b": True}    # 0.004 < 0.01/2, then 0.006 < 0.01
    assert holm_flags({"a": 0.012, "b": 0.004}) == {"a": False, "b": True}
    assert holm_flags({"a": float("nan"), "b": 0.001}) == {"a": False, "b": True}


def test_units_are_flights_or_stretches_of_one_flight():
    t = np.tile(np.arange(200) * 0.05, 3)
    f = np.repeat([0, 2, 5], 200)
    u, names, kind = units_of(t, f, ["a", "b", "c", "d", "e", "f"])
    assert kind == "flight" and names == ["a", "c", "f"] and list(np.unique(u)) == [0, 1, 2]
    u, names, kind = units_of(t[:200], f[:200], ["a"])
    assert kind == "stretch" and len(names) == 4 and np.all(np.diff(u) >= 0)
    assert n_stretches(60) == 0 and n_stretches(100) == 2


def _flights(slopes, n=600, seed=0, noise=0.1):
    """Rows of flights y = slope_f · x + noise (AR(1), like a derivative target), x a manoeuvre."""
    rng = np.random.default_rng(seed)
    x, y, fl, t = [], [], [], []
    for i, s in enumerate(slopes):
        tt = np.arange(n) * 0.05
        xi = np.sin(0.7 * tt + i) + 0.5 * np.sin(2.3 * tt)
        e = np.zeros(n)
        for k in range(1, n):
            e[k] = 0.5 * e[k - 1] + noise * rng.standard_normal()
        x.append(xi), y.append(s * xi + e), fl.append(np.full(n, i)), t.append(tt)
    return np.concatenate(x), np.concatenate(y), np.concatenate(fl), np.concatenate(t)


def _model():
    v = sp.Symbol("vx")
    return TermModel((-0.28 * v,), ("⟨minus_kD_vx⟩",), lo=(0.0,), hi=(math.inf,), intercept_bounds=(0.0, 0.0))


def test_physical_fit_flags_a_drag_that_moves_between_flights_and_widens_its_interval():
    x, y, fl, t = _flights([-0.28 * 0.3, -0.28 * 1.4, -0.28 * 0.5, -0.28 * 1.2])
    cols = {"vx": x}
    pooled = physical_fit(_model(), cols, y, time_blocks(t, fl))
    fit = physical_fit(_model(), cols, y, time_blocks(t, fl), flight=fl, t=t, sources=["a", "b", "c", "d"])
    c = fit.constancy["⟨minus_kD_vx⟩"]
    assert c.unit == "flight" and c.constant is False and c.p < 1e-6
    assert sorted(round(v[0], 1) for v in c.per_unit.values()) == [0.3, 0.5, 1.2, 1.4]
    lo0, hi0 = pooled.intervals["⟨minus_kD_vx⟩"]
    lo1, hi1 = fit.intervals["⟨minus_kD_vx⟩"]
    assert hi1 - lo1 > 3 * (hi0 - lo0) and lo1 >= 0.0        # wider, never past the physical bound
    assert "NOT vehicle constants" in constancy_sentence(fit.constancy)
    assert "1/s" in constancy_line(fit.constancy)          # the drag in physical units too


def test_physical_fit_keeps_a_constant_drag_and_its_interval_covers_it():
    x, y, fl, t = _flights([-0.28] * 4, seed=3)
    fit = physical_fit(_model(), {"vx": x}, y, time_blocks(t, fl), flight=fl, t=t, sources=["a", "b", "c", "d"])
    c = fit.constancy["⟨minus_kD_vx⟩"]
    assert c.constant is True and c.between is not None
    lo, hi = fit.intervals["⟨minus_kD_vx⟩"]
    assert lo <= 1.0 <= hi
    assert constancy_sentence(fit.constancy) == ""


def test_one_flight_is_tested_in_stretches_and_says_it_cannot_see_other_flights():
    x, y, fl, t = _flights([-0.28], n=800)
    y = y + np.where(t > 20, -0.28 * 2.0 * x, 0.0)        # the drag triples half-way: something unmodelled
    fit = physical_fit(_model(), {"vx": x}, y, time_blocks(t, fl), flight=fl, t=t, sources=["a"])
    c = fit.constancy["⟨minus_kD_vx⟩"]
    assert c.unit == "stretch" and c.between is None and c.constant is False
    assert "one flight cannot show how flights differ" in constancy_line(fit.constancy)


def test_constancy_round_trips_through_json():
    c = Constancy("flight", {"a": (1.0, 0.9, 1.1), "b": (1.2, 1.1, 1.3)}, 0.003, False, (0.8, 1.4), 0.1, (0.28, "1/s"))
    assert Constancy.from_dict(c.to_dict()) == c
    assert "per_flight" in c.to_dict()
    s = Constancy("stretch", {"0-5 s": (1.0, 0.9, 1.1)}, float("nan"), None)
    back = Constancy.from_dict(s.to_dict())
    assert back.unit == "stretch" and back.constant is None and math.isnan(back.p)


def test_each_unit_is_fitted_without_the_physics_bounds_for_the_test():
    """An estimate pinned at its bound is not an estimate (its replicates pile up on the bound, its
    standard error falls towards 0 and its weight decides Q alone): each unit is fitted without the
    physics bounds (constancy.unit_bounds), held coefficients staying held. A flight whose drag
    pushes through the bound 0 says how far, and its disagreement is seen; flights that agree
    near the bound are not split by it."""
    from droneid.fitting.constancy import unit_bounds
    lo, hi = unit_bounds([0.0, 1.0, -np.inf, 0.0], [np.inf, 1.0, 0.0, 0.0])     # (1, 1), (0, 0): held
    assert lo.tolist() == [-np.inf, 1.0, -np.inf, 0.0] and hi.tolist() == [np.inf, 1.0, np.inf, 0.0]
    lo, hi = unit_bounds([0.0, 1.0, 0.0], [np.inf, 1.0, 2.0], tested=[1, 2])   # the others keep theirs
    assert lo.tolist() == [0.0, 1.0, -np.inf] and hi.tolist() == [np.inf, 1.0, np.inf]
    names = ["a", "b", "c", "d", "pushed"]
    x, y, fl, t = _flights([-0.28, -0.28, -0.28, -0.28, +0.1], seed=3, noise=0.02)
    c = physical_fit(_model(), {"vx": x}, y, time_blocks(t, fl), flight=fl, t=t, sources=names).constancy["⟨minus_kD_vx⟩"]
    assert c.per_unit["pushed"][0] < -0.3 and c.per_unit["pushed"][2] < 0      # -0.1/0.28 = -0.36, through 0
    assert c.constant is False and c.p < 1e-6
    # five flights with no drag, noisy: some fall below 0, none is pinned there, and they agree
    x, y, fl, t = _flights([0.0] * 5, seed=4, noise=0.3)
    fit = physical_fit(_model(), {"vx": x}, y, time_blocks(t, fl), flight=fl, t=t, sources=names)
    c = fit.constancy["⟨minus_kD_vx⟩"]
    assert min(v[0] for v in c.per_unit.values()) < 0 and c.constant is True
    assert fit.model.coefs[0] >= 0 and fit.intervals["⟨minus_kD_vx⟩"][0] >= 0      # the model keeps its bound


def test_a_tiny_spread_is_not_a_finding():
    """Holm-significant but τ under 1 % of the value: still constant (the minimum effect)."""
    x, y, fl, t = _flights([-0.28, -0.28 * 1.004, -0.28 * 0.996, -0.28], seed=5, noise=0.001)
    fit = physical_fit(_model(), {"vx": x}, y, time_blocks(t, fl), flight=fl, t=t, sources=["a", "b", "c", "d"])
    c = fit.constancy["⟨minus_kD_vx⟩"]
    assert c.p < 1e-6 and 0 < c.tau < 0.01          # significant, but a spread of under 1 %
    assert c.constant is True
    x, y, fl, t = _flights([-0.28, -0.28 * 1.04, -0.28 * 0.96, -0.28], seed=5, noise=0.001)
    fit = physical_fit(_model(), {"vx": x}, y, time_blocks(t, fl), flight=fl, t=t, sources=["a", "b", "c", "d"])
    assert fit.constancy["⟨minus_kD_vx⟩"].constant is False     # 4 %: a finding


def test_leads_point_to_what_moves_a_constant_and_what_the_diagnosis_said():
    from droneid.fitting.constancy import leads
    bad = {"minus_kD_vx": Constancy("flight", {"a": (0.2, 0.1, 0.3), "b": (1.4, 1.3, 1.5)}, 1e-9, False)}
    good = {"minus_kD_vx": Constancy("flight", {"a": (1.0, 0.9, 1.1), "b": (1.0, 0.9, 1.1)}, 0.9, True)}
    diag = {"not_detected": ["wind"], "untestable": {"anisotropic_drag": "why"}, "effects_added": []}
    text = leads(bad, diag)
    assert "wind (not detected)" in text and "anisotropic_drag (untestable)" in text and "thrust" not in text
    assert "a wind that differs between flights" in text and "payload" not in text
    thrust = {"sum_rpm_sq_z": Constancy("flight", {"a": (0.9, 0.89, 0.91), "b": (1.2, 1.19, 1.21)}, 1e-9, False)}
    assert "payload" in leads(thrust, diag)
    assert leads(good, diag) == ""
    # a command-driven vehicle's curve holds the thrust curve and its battery compensation: log171's
    # leads said 'battery_sag (not tried), thrust_curve (not tried)' with both in the model
    from types import SimpleNamespace
    text = leads(thrust, diag, curve=SimpleNamespace(expo=0.0, voltage=True))
    assert "thrust_curve (in the model: the curve's shape e = 0.00)" in text
    assert "battery_sag (in the model: the curve's battery compensation)" in text and "not tried)" in text
    assert "battery_sag (the curve's battery compensation not kept)" in leads(
        thrust, diag, curve=SimpleNamespace(expo=0.5, voltage=False))


def test_collinear_physical_terms_are_tied_into_the_combination_the_data_identify():
    """Issue 36: a command map Σu² + Σu near hover is collinear (VIF > 100); the pair is fitted
    as one scale on its sum, never held at a nominal 1 nobody measured, and that scale is
    measured (the planted thrust near hover is about half the two nominal terms' sum)."""
    import sympy as sp

    from droneid.core.expressions import symbol
    from droneid.fitting.terms import TermModel
    from droneid.dataset.validation import time_blocks
    rng = np.random.default_rng(0)
    n = 2000
    u, vz = 0.5 + 0.03 * rng.standard_normal(n), rng.standard_normal(n)
    t, fl = np.arange(n) * 0.05, np.zeros(n, int)
    y = 9.81 * (0.6 * u ** 2 / 0.25 + 0.4 * u / 0.5) - 9.81 - 0.3 * vz + 0.05 * rng.standard_normal(n)
    m = TermModel((9.81 / 0.25 * symbol("motor1") ** 2, 9.81 / 0.5 * symbol("motor1"), -symbol("vz")),
                  ("⟨sq⟩", "⟨lin⟩", "⟨drag⟩"), lo=(0, 0, 0), hi=(np.inf,) * 3, intercept_bounds=(0, 0),
                  offset=sp.Float(-9.81))
    ev = physical_fit(m, {"motor1": u, "vz": vz}, y, time_blocks(t, fl), flight=fl, t=t, sources=("a",))
    assert ev.held == {}
    assert ev.model.labels == ("⟨sq + lin⟩", "⟨drag⟩")
    lo, hi = ev.intervals["⟨sq + lin⟩"]
    assert 0.49 < lo <= hi < 0.51                      # pinned down, near half the nominal sum
    pred = ev.model.predict({"motor1": u, "vz": vz}, n)
    assert np.sqrt(np.mean((pred - y) ** 2)) < 0.1      # noise 0.05 m/s²; both held at 1 would be ~10
    assert "collinear" in ev.notes[0] and "one scale" in ev.notes[0]


def test_one_thrust_scale_across_the_targets():
    """The thrust scale along x, y and z is one constant of the vehicle: scales that differ by more
    than their intervals allow are flagged (the x500 hover: 0.2 along x, 0.98 along z), in the
    verdict of every target that takes part; scales that agree, a spread under MIN_TAU_REL, one
    term alone and a role not shared (drag) are not."""
    from droneid.fitting.constancy import across_targets
    apart = across_targets({"thrust": {"⟨t_x⟩": (0.202, 0.0825, 0.322), "⟨t_y⟩": (0.14, 0.05, 0.227),
                                       "⟨t_z⟩": (0.977, 0.974, 0.987)},
                            "drag": {"⟨d_x⟩": (0.2, 0.1, 0.3), "⟨d_z⟩": (3.0, 2.9, 3.1)}})
    assert set(apart) == {"thrust"}
    c = apart["thrust"]
    assert c.constant is False and c.p < 1e-6
    said = c.sentence(["⟨t_x⟩"])
    assert said.startswith("NOT ONE THRUST SCALE: ⟨t_x⟩ 0.202 [0.0825, 0.322]") and "⟨t_z⟩ 0.977" in said
    assert c.sentence(["⟨other⟩"]) == ""
    agree = across_targets({"thrust": {"⟨t_x⟩": (0.991, 0.9725, 1.009), "⟨t_y⟩": (0.987, 0.9645, 1.012),
                                       "⟨t_z⟩": (0.989, 0.9812, 0.9968)}})["thrust"]
    assert agree.constant is True and agree.p > 0.5 and agree.sentence(["⟨t_x⟩"]) == ""
    # significant but under 1 %: long flights make any difference significant; not a finding
    tiny = across_targets({"thrust": {"⟨t_x⟩": (1.000, 0.9995, 1.0005), "⟨t_z⟩": (1.004, 1.0035, 1.0045)}})["thrust"]
    assert tiny.p < ALPHA and tiny.constant is True
    assert across_targets({"thrust": {"⟨t_z⟩": (0.98, 0.97, 0.99)}}) == {}


def test_sentences_end_with_a_full_stop():
    from droneid.core.text import sentences
    assert sentences("a beats b (RMSE 1 vs 2)", "", "NOT vehicle constants: x", "It sits on e = 0.") == \
        "a beats b (RMSE 1 vs 2). NOT vehicle constants: x. It sits on e = 0."
    assert sentences("", "  ") == ""


def test_a_spread_reads_as_a_person_writes_it():
    """'spread τ nan %' and 'spread τ 1.5e+02 %: constant' reached a user (walkthrough): no
    relative size is '—', a wide spread the test does not flag is 'constant within its noise'."""
    from droneid.fitting.constancy import constancy_line, spread_text
    assert (spread_text(float("nan")), spread_text(150.4), spread_text(1.27)) == ("—", "150 %", "1.3 %")
    wide = {"minus_kD_vz": Constancy("stretch", {"a": (0.0, 0.0, 0.4), "b": (0.42, 0.0, 0.9)}, 0.23, True,
                                     tau=0.3)}
    line = constancy_line(wide)
    assert "spread τ 143 %: constant within its noise" in line and "e+" not in line
    held = {"minus_kD_vz": Constancy("stretch", {"a": (0.0, 0.0, 0.4), "b": (0.0, 0.0, 0.9)}, 1.0, True, tau=0.0)}
    assert "spread τ —: constant" in constancy_line(held) and "nan" not in constancy_line(held)


def test_a_unit_without_spread_carries_no_information():
    """A unit whose standard error is 0 (its rows do not move the term: the solver's value, no
    spread) does not count; it was floored at 1e-9 and its weight decided Q alone."""
    h = heterogeneity([1.0, 1.05, 5.0], [0.1, 0.1, 0.0], df=[9, 9, 9])
    both = heterogeneity([1.0, 1.05], [0.1, 0.1], df=[9, 9])
    assert h["p"] == both["p"] and h["p"] > 0.5 and h["mean"] == both["mean"]
    assert math.isnan(heterogeneity([1.0, 5.0], [0.1, 0.0])["p"])          # one unit left: untestable
    assert heterogeneity([1.0, 1.05, 5.0], [0.1, 0.1, 1e-14])["p"] == heterogeneity([1.0, 1.05], [0.1, 0.1])["p"]
    # nor is it listed among the units, nor counted in what a new flight should give
    from droneid.fitting.constancy import constancies, new_flight_expectation
    ivs = [np.array([[v - 0.2], [v + 0.2]]) for v in (1.0, 1.05, 5.0)]
    c = constancies("flight", ["a", "b", "c"], [[1.0], [1.05], [5.0]], [[0.1], [0.1], [0.0]], ivs, {0: "k"},
                    dfs=[9, 9, 9])["k"]
    assert set(c.per_unit) == {"a", "b"} and c.p == both["p"]
    two = constancies("flight", ["a", "b"], [[1.0], [1.05]], [[0.1], [0.1]], ivs[:2], {0: "k"}, dfs=[9, 9])["k"]
    assert new_flight_expectation(1.0, 0.9, 1.1, c.to_dict()) == new_flight_expectation(1.0, 0.9, 1.1, two.to_dict())


def test_a_payload_per_flight_is_one_thrust_factor_on_every_axis():
    """A payload or a battery per flight scales every axis's thrust per unit mass by one factor:
    x's scale moving with z's holds as a ratio; x's moving while z's stays still does not; the
    reference is the most precise other axis, and a scale that holds is not tested."""
    rng = np.random.default_rng(4)
    flights = [f"f{i}" for i in range(5)]
    factor = np.array([1.0, 0.96, 1.04, 0.93, 1.07])

    def record(values, se, constant):
        per = {f: (float(v), float(v - 1.96 * se), float(v + 1.96 * se)) for f, v in zip(flights, values)}
        return Constancy("flight", per, 1e-6 if constant is False else 0.5, constant)

    se = 0.004
    x = record(factor * 0.99 + rng.normal(0, se, 5), se, False)
    z_with = record(factor + rng.normal(0, se / 2, 5), se / 2, False)
    z_still = record(1.0 + rng.normal(0, se / 2, 5), se / 2, True)
    y_loose = record(1.0 + rng.normal(0, 0.05, 5), 0.05, True)

    held = one_factor_per_flight({"⟨x⟩": x, "⟨z⟩": z_with}, {"⟨x⟩": x, "⟨y⟩": y_loose, "⟨z⟩": z_with})
    assert set(held) == {"⟨x⟩", "⟨z⟩"}
    assert "⟨x⟩ / ⟨z⟩" in held["⟨x⟩"] and held["⟨z⟩"] == held["⟨x⟩"]   # the precise axis, not y; one test
    assert all(s.endswith("constant (the axes' thrust moves together from flight to flight)") for s in held.values())

    still = one_factor_per_flight({"⟨x⟩": x}, {"⟨x⟩": x, "⟨y⟩": y_loose, "⟨z⟩": z_still})
    assert "still NOT constant (⟨z⟩ does not move with it)" in still["⟨x⟩"]
    assert one_factor_per_flight({"⟨x⟩": x}, {"⟨x⟩": x}) == {}         # no other axis: nothing to test


def test_a_condition_holds_a_constant_only_if_its_noise_would_still_show_the_spread():
    """explained(): a refit that holds because its standard errors grew until the old spread
    hides in them is "not told apart"; one that holds with the old precision is "constant"; one
    that still moves is "still NOT constant"."""
    flights = [f"f{i}" for i in range(5)]

    def record(values, se, constant, df=9.0):
        per = {f: (float(v), float(v - 1.96 * se), float(v + 1.96 * se)) for f, v in zip(flights, values)}
        return Constancy("flight", per, math.nan, constant, noise={f: (se, df) for f in flights})

    spread = np.array([0.9, 1.1, 1.0, 1.25, 0.8])
    before = {"⟨k⟩": record(spread, 0.02, False)}
    same = record(np.full(5, 1.0) + np.array([0.01, -0.01, 0.0, 0.005, -0.005]), 0.02, True)
    blurred = record(spread, 0.3, True)
    moving = record(spread, 0.02, False)
    assert explained(before, {"⟨k⟩": same}) == {"⟨k⟩": ("constant", 1.0)}
    word, growth = explained(before, {"⟨k⟩": blurred})["⟨k⟩"]
    assert word == "not told apart" and growth == pytest.approx(15.0)
    assert explained(before, {"⟨k⟩": moving})["⟨k⟩"][0] == "still NOT constant"
    assert explained(before, {"⟨other⟩": same}) == {}          # nothing to compare with
    untested = Constancy("flight", same.per_unit, math.nan, None, noise=same.noise)
    assert explained(before, {"⟨k⟩": untested})["⟨k⟩"][0] == "untestable"
    stretches = Constancy("stretch", same.per_unit, 0.5, True, noise=same.noise)
    assert explained(before, {"⟨k⟩": stretches})["⟨k⟩"][0] == "untestable"   # not the same units


def test_a_payload_test_against_a_blurred_axis_tells_nothing():
    """The payload lead's power check: a reference axis so uncertain per flight that the moved
    term's own spread would not show through the ratios is "not told apart", not "constant"."""
    flights = [f"f{i}" for i in range(5)]

    def record(values, se):
        return Constancy("flight", {f: (float(v), float(v - 1.96 * se), float(v + 1.96 * se))
                                    for f, v in zip(flights, values)}, 1e-6, False)

    x = record([1.0, 0.96, 1.04, 0.93, 1.07], 0.004)
    z = record([1.0, 1.0, 1.0, 1.0, 1.0], 0.2)
    said = one_factor_per_flight({"⟨x⟩": x}, {"⟨x⟩": x, "⟨z⟩": z})["⟨x⟩"]
    assert said.endswith("not told apart (⟨z⟩ too uncertain per flight to show the spread ⟨x⟩ had)"), said


def test_the_payload_test_reads_each_flight_s_noise_as_the_constancy_test_did():
    """The ratio's standard errors and degrees of freedom are the ones the constancy test read
    (Constancy.noise), not the narrower percentile intervals: the same spread flagged with the
    intervals' noise is not flagged with the test's own."""
    flights = [f"f{i}" for i in range(5)]
    x_vals = 1.0 + np.array([0.0, 0.01, -0.01, 0.02, -0.02])

    def record(values, se, noise=None):
        per = {f: (float(v), float(v - 1.96 * se), float(v + 1.96 * se)) for f, v in zip(flights, values)}
        return Constancy("flight", per, 1e-6, False, noise={f: noise for f in flights} if noise else {})

    z = record(np.ones(5), 0.001)
    narrow = one_factor_per_flight({"⟨x⟩": record(x_vals, 0.002)}, {"⟨z⟩": z})["⟨x⟩"]
    own = one_factor_per_flight({"⟨x⟩": record(x_vals, 0.002, (0.02, 4.0))}, {"⟨z⟩": z})["⟨x⟩"]
    assert "still NOT constant" in narrow and "still NOT constant" not in own, (narrow, own)
