"""The trust guards of identify (droneid.fitting.terms, droneid.identify.ladder) on data with a planted law."""
import math
from types import SimpleNamespace

import numpy as np
import pytest
import sympy as sp

from droneid.core.expressions import symbol
from droneid.core.regression import blocked_cv
from droneid.fitting.terms import TermModel, drag_slope, plausible, trim_terms
from droneid.dataset.validation import validation_blocks

v, a = symbol("vx"), symbol("pitch")


@pytest.fixture
def data():
    """vx_dot = 9.81 pitch − 0.3 vx + noise, five 'flights' of 200 samples."""
    rng = np.random.default_rng(0)
    n = 1000
    cols = {"vx": rng.uniform(-2, 2, n), "pitch": rng.uniform(-0.3, 0.3, n)}
    y = 9.81 * cols["pitch"] - 0.3 * cols["vx"] + rng.normal(0, 0.1, n)
    flight = np.repeat(np.arange(5), 200)
    t = np.tile(np.arange(200) * 0.05, 5)
    return cols, y, flight, t


def test_term_model_recovers_the_planted_law(data):
    cols, y, flight, t = data
    m = TermModel((a, v), ("pitch", "vx")).fit(cols, y)
    assert m.coefs == pytest.approx((9.81, -0.3), rel=0.02)
    blocks, how = validation_blocks(t, flight)
    assert "leave-one-flight-out over 5" in how and set(blocks) == set(range(5))
    assert m.cv_rmse(cols, y, blocks) == pytest.approx(0.1, rel=0.1)


def test_validation_blocks_within_flights_when_there_are_few():
    t = np.arange(400) * 0.05
    blocks, how = validation_blocks(t, np.zeros(400, int))
    assert "contiguous time blocks" in how and len(set(blocks)) == 8
    assert np.all(np.diff(blocks) >= 0)  # contiguous in time


def test_blocked_cv_predicts_each_block_without_it():
    y = np.r_[np.zeros(50), np.ones(50)]
    A = np.ones((100, 1))
    pred = blocked_cv(A, y, np.r_[np.zeros(50, int), np.ones(50, int)])
    assert np.allclose(pred[:50], 1.0) and np.allclose(pred[50:], 0.0)  # the other block's mean


def test_trim_drops_a_cancelling_pair_a_duplicate_and_a_useless_term(data):
    cols, y, flight, t = data
    blocks, _ = validation_blocks(t, flight)
    # a cancelling pair: 20·sin(vx) − 20·vx·(1 − vx²/6) is ~0 in range and huge outside;
    # a duplicate of pitch (scaled); a term that only fits noise
    evolved = (sp.sin(v), v * (1 - v ** 2 / 6), 2.0 * a, sp.cos(37 * v))
    m = TermModel((a, v) + evolved, ("pitch", "vx", "sin", "cubic", "2pitch", "cos37"))
    trimmed, notes = trim_terms(m, cols, y, blocks, keep_first=2)
    assert trimmed.labels == ("pitch", "vx")
    text = " ".join(notes)
    assert "duplicates pitch" in text and "validation error" in text
    assert trimmed.coefs == pytest.approx((9.81, -0.3), rel=0.02)


def test_trim_keeps_a_real_missing_term():
    rng = np.random.default_rng(1)
    n = 1000
    cols = {"vx": rng.uniform(-2, 2, n), "pitch": rng.uniform(-0.3, 0.3, n)}
    y = 9.81 * cols["pitch"] - 0.3 * cols["vx"] - 0.2 * np.abs(cols["vx"]) * cols["vx"] + rng.normal(0, 0.05, n)
    blocks, _ = validation_blocks(np.tile(np.arange(200) * 0.05, 5), np.repeat(np.arange(5), 200))
    m = TermModel((a, v, sp.Abs(v) * v), ("pitch", "vx", "quadratic drag"))
    trimmed, notes = trim_terms(m, cols, y, blocks, keep_first=2)
    assert "quadratic drag" in trimmed.labels and not notes
    assert trimmed.coefs[2] == pytest.approx(-0.2, rel=0.1)


def test_plausible_rejects_a_term_that_blows_up_just_outside_the_range():
    ranges = {"vx": (-1.5, 1.5)}
    assert plausible(-0.3 * v, ranges, bound=20).ok
    blow = plausible(-0.3 * v + 0.01 * v ** 9, ranges, bound=20)  # 0.38 at 1.5, 1.6 at 1.8 ... 14 at 2.1
    assert plausible(-0.3 * v + 0.01 * v ** 9, ranges, bound=20, margin=0.0).ok
    assert blow.max_abs > plausible(-0.3 * v + 0.01 * v ** 9, ranges, bound=20, margin=0.0).max_abs
    assert not plausible(-0.3 * v + 0.01 * v ** 15, ranges, bound=20).ok
    assert not plausible(1 / (v - 1.6), ranges, bound=20).ok


def test_drag_slope_flags_a_velocity_term_that_turns_over():
    rows = {"pitch": np.linspace(-0.2, 0.2, 5)}
    assert drag_slope(9.81 * a - 0.3 * v, "vx", rows, 2.0) == pytest.approx(-0.3)
    assert drag_slope(9.81 * a - 0.3 * v - 0.2 * sp.Abs(v) * v, "vx", rows, 2.0) <= -0.3 + 1e-9
    wavy = -0.528 * v + 0.52 * v * sp.cos(v ** 2) ** 3  # found by SNGP on the Crazyflie squares
    assert drag_slope(wavy, "vx", rows, 2.0) > 0.5
    assert drag_slope(9.81 * a, "vx", rows, 2.0) == -math.inf  # no velocity: nothing to check


def test_functions_of_functions_are_unreadable(data):
    from droneid.fitting.terms import nested_functions
    assert nested_functions(v ** 2 * a) == 0 and nested_functions(sp.sin(v) * sp.cos(a)) == 1
    assert nested_functions(sp.cos(sp.sin(v) + 1)) == 2
    cols, y, flight, t = data
    blocks, _ = validation_blocks(t, flight)
    y2 = y + 0.5 * np.cos(np.sin(3 * cols["vx"]))  # even if it fits, nobody can read it aloud
    m = TermModel((a, v, sp.cos(sp.sin(3 * v))), ("pitch", "vx", "cos(sin(3 vx))"))
    trimmed, notes = trim_terms(m, cols, y2, blocks, keep_first=2)
    assert trimmed.labels == ("pitch", "vx") and "unreadable" in notes[0]


def test_negligible_addends_are_dropped_from_the_shown_equation():
    from droneid.fitting.terms import drop_negligible
    r, w = symbol("roll"), symbol("rpm4")
    cols = {"roll": np.linspace(0.1, 0.5, 20), "rpm4": np.linspace(5e4, 1.4e5, 20), "vx": np.linspace(-1, 1, 20)}
    e = 1.1e-10 * (4 * r ** 2 * w ** 2 + w + 3.142) * sp.sin(v)
    assert drop_negligible(e, cols, 20) == 1.1e-10 * 4 * r ** 2 * w ** 2 * sp.sin(v)
    assert drop_negligible(v + 0.5, cols, 20) == v + 0.5  # both parts matter


def _rung(rmse_test, rmse_validation, at_bound=None, constraint_rmse_test=float("nan")):
    """What a verdict reads of a rung (droneid.identify.ladder.Rung's attributes)."""
    return SimpleNamespace(rmse_test=rmse_test, rmse_validation=rmse_validation, at_bound=at_bound or {},
                           constraint_rmse_test=constraint_rmse_test)


def test_verdicts_read_as_what_they_are():
    from droneid.fitting.verdict import verdict
    rung = _rung
    emp = rung(1.0, 1.0)
    v = verdict("vx_dot", rung(0.6, 0.5), emp, False, False, 2.0)
    assert v.kind == "better" and "beats the empirical model by 40 % on the test flights" in v.text
    assert "RMSE 0.6 vs 1 m/s²" in v.text and "σ(vx_dot) 2" in v.text   # absolute errors beside the %
    assert verdict("vx_dot", rung(0.98, 0.9), emp, True, False).kind == "no better"
    w = verdict("vx_dot", rung(1.5, 0.9), emp, True, False)
    assert w.kind == "worse" and "WORSE" in w.text
    # better on the test flights but not in validation: no claim
    assert verdict("vx_dot", rung(0.6, 1.2), emp, False, False).kind == "no better"
    nan = float("nan")
    v = verdict("vx_dot", rung(nan, 0.5), rung(nan, 1.0), False, False)
    assert "on validation blocks of the training flights (no test data)" in v.text and "50 %" in v.text
    # the copter34 bench case: a target that does not vary is no "+100 %" success
    assert verdict("vy_dot", rung(0.0, 0.0), rung(0.0, 0.0), False, False, y_spread=0.0).kind == "no verdict"


def test_a_model_outside_its_physics_is_not_to_be_trusted_however_well_it_fits():
    from droneid.fitting.verdict import verdict
    emp = _rung(1.0, 1.0)
    pulled = _rung(0.5, 0.5, at_bound={"⟨minus_kD_vz⟩": 0.0})
    v = verdict("vz_dot", pulled, emp, False, False)
    assert v.kind == "not to be trusted" and "minus_kD_vz" in v.text and "+50 %" in v.text
    broken = _rung(0.5, 0.5, constraint_rmse_test=7.3)
    assert verdict("vz_dot", broken, emp, False, False, gamma=0.05).kind == "not to be trusted"
    # an e_c the prior's own refit has too is explained, not a fault of the model
    assert verdict("vz_dot", broken, emp, False, False, gamma=0.05,
                   reference=_rung(1.0, 1.0, constraint_rmse_test=7.0)).kind == "better"


def test_physical_terms_that_offset_each_other_do_not_cost_a_real_evolved_term():
    """A command map a·Σu² + b·Σu has terms of opposite sign by design; a real missing term
    beside it is kept (only cancellation beyond the physical terms' own counts)."""
    rng = np.random.default_rng(3)
    n = 1000
    u = rng.uniform(0.4, 0.8, n)
    cols = {"u": u, "vx": rng.uniform(-2, 2, n)}
    U, V = symbol("u"), v
    y = 40 * u ** 2 - 30 * u - 0.3 * cols["vx"] - 0.2 * np.abs(cols["vx"]) * cols["vx"] + rng.normal(0, 0.02, n)
    blocks, _ = validation_blocks(np.tile(np.arange(200) * 0.05, 5), np.repeat(np.arange(5), 200))
    m = TermModel((U ** 2, U, V, sp.Abs(V) * V), ("u²", "u", "vx", "quadratic drag"))
    trimmed, notes = trim_terms(m, cols, y, blocks, keep_first=3)
    assert "quadratic drag" in trimmed.labels, notes


def test_rows_where_a_feature_is_not_finite_are_left_out_and_counted():
    """A folded feature such as a motor's share of thrust is 0/0 where every motor stops for a
    sample; no fit or SNGP run may see such a row (it would fail every run), and the notes say so."""
    from droneid.dataset.data import Dataset
    from droneid.identify.problem import _finite_rows
    from priors.base import PriorFeature
    n = 50
    u = np.linspace(1.0, 2.0, n)
    u[[7, 31]] = 0.0
    X = np.column_stack([u, u])
    ds = Dataset(X, np.ones(n), np.arange(n) * 0.05, ("rpm1", "rpm2"), "vz_dot", np.zeros(n, int))
    share = PriorFeature("share", symbol("rpm1") / (symbol("rpm1") + symbol("rpm2")), "", "other")
    notes = []
    kept = _finite_rows(ds, (share,), "training", notes)
    assert len(kept) == n - 2 and np.all(kept.column("rpm1") > 0)
    assert notes and notes[0].startswith("2 training row(s) left out") and "share on 2" in notes[0]
    assert _finite_rows(kept, (share,), "training", []) is kept     # nothing to drop: the same rows


def test_constraint_samples_where_a_feature_is_undefined_are_left_out():
    """The rotor-thrust constraint "no thrust at rest" samples every rotor speed at 0, where a
    motor's share of thrust is 0/0; those samples are left out instead of failing every run."""
    from droneid.core.constraint_samples import ConstraintSamples
    from droneid.fitting.terms import defined_samples
    from priors.base import PriorFeature
    X = np.array([[0.0, 0.0], [1.0, 2.0], [0.0, 0.0], [3.0, 1.0]])
    cs = ConstraintSamples(X, np.zeros(4), np.array([-9.81, 0.0, -9.81, 0.0]), np.array([0, 1, 0, 1]),
                           ("rpm1", "rpm2"), ("free fall", "level"))
    share = PriorFeature("share", symbol("rpm1") / (symbol("rpm1") + symbol("rpm2")), "", "other")
    kept, n = defined_samples(cs, (share,))
    assert n == 2 and len(kept) == 2 and kept.X.tolist() == [[1.0, 2.0], [3.0, 1.0]]
    assert kept.names == cs.names and kept.bound.tolist() == [0.0, 0.0]
    assert defined_samples(kept, (share,)) == (kept, 0)


def test_a_verdict_says_when_predicting_zero_beats_both_models():
    """x500_sitl_events: both models err by about twice the target's spread (0.0298 vs 0.0306,
    σ 0.0164) and the verdict said "keep the empirical model"."""
    from droneid.identify.ladder import trivial_errors
    from droneid.fitting.verdict import verdict
    nan = float("nan")
    rng = np.random.default_rng(0)
    y = rng.normal(0.0, 0.0164, 400)
    blocks = np.repeat(np.arange(8), 50)
    trivial = trivial_errors(y, blocks, np.array([]))
    assert trivial["zero"] == pytest.approx(0.0164, rel=0.1)
    assert trivial["the training mean"] == pytest.approx(0.0164, rel=0.1)
    v = verdict("vx_dot", _rung(nan, 0.0298), _rung(nan, 0.0306), False, False, 0.0164, trivial=trivial)
    assert v.kind == "no better" and "NEITHER MODEL is 5 % better than predicting" in v.text
    assert "keep the empirical model" not in v.text and "0.0298" in v.text and "0.0306" in v.text
    # a model that beats zero by the margin keeps its verdict
    v = verdict("vx_dot", _rung(nan, 0.01), _rung(nan, 0.0306), False, False, 0.0164, trivial=trivial)
    assert v.kind == "better"
    # one that beats the empirical model but not zero by the margin is no model of the target
    # (x500's hover after its thrust curve: 0.0157 against zero's 0.0164)
    e0 = min(trivial.values())
    v = verdict("vx_dot", _rung(nan, 0.97 * e0), _rung(nan, 0.0306), False, False, 0.0164, trivial=trivial)
    assert v.kind == "no better" and v.use == "neither" and "NEITHER MODEL" in v.text
    # on test rows the baselines are measured there (the training mean carried over)
    t = trivial_errors(np.full(10, 2.0), None, np.full(5, 1.0))
    assert t == {"zero": 1.0, "the training mean": 1.0}


def test_the_verdict_says_which_model_to_use():
    """Issue 36.6: the identified model where it wins (or nothing could be measured), the empirical
    one where it is no better, worse or not to be trusted, neither where predicting zero or the
    mean beats both; a result written before the field existed reads the same from its verdict."""
    from droneid.fitting.verdict import Verdict, model_to_use
    assert [Verdict(k, "t").use for k in ("better", "no verdict", "no better", "worse", "not to be trusted")] == \
        ["identified", "identified", "empirical", "empirical", "empirical"]
    assert Verdict("no better", "t", use="neither").use == "neither"
    assert model_to_use("no better", "", "vz_dot: NEITHER MODEL beats predicting zero ...") == "neither"
    assert model_to_use("worse", "identified") == "identified"      # a recorded choice is kept
