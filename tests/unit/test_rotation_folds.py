"""Leave-one-flight-out fits by downdating (droneid.rotation.folds, issue 38): the robust fit with
one free intercept per group is the one-hot robust fit without its columns, and the folds of the
rotational choice recover planted truth from sums computed once."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.simulation.openloop import StateLog
from droneid.core.regression import robust_fit, robust_fit_grouped
from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM
from droneid.rotation.model import TranslationModel, fit_rotation, fit_translation, translation_rows
from droneid.rotation.decay import damping_folds, fit_damping
from droneid.rotation.folds import downdatable, rotation_folds, translation_folds
from test_rotation_ladder import _decaying_flight
from test_rotation_planted import DRAG_COEF, DRAG_TERMS, LAYOUT, _balanced_flight


def test_grouped_robust_fit_is_the_one_hot_fit():
    rng = np.random.default_rng(0)
    n, G = 3000, 6
    A = rng.normal(size=(n, 4))
    g = rng.integers(0, G, n)
    y = A @ [1.0, 2.0, 0.5, -1.0] + rng.normal(0, 0.5, G)[g] + 0.1 * rng.standard_t(2, size=n)
    for first in (0.0, 1.5):                      # the bound inactive, then active
        lo = np.array([first, -np.inf, -np.inf, -np.inf])
        one_hot = robust_fit(np.hstack([A, np.eye(G)[g]]), y, lo=np.concatenate([lo, np.full(G, -np.inf)]))
        grouped = robust_fit_grouped(A, y, g, lo=lo)
        np.testing.assert_allclose(grouped.beta, one_hot.beta, atol=1e-10)
        np.testing.assert_allclose(grouped.weights, one_hot.weights, atol=1e-9)
    assert grouped.beta[0] == 1.5 and grouped.at_bound[0]


@pytest.mark.slow   # ~10 s: three simulated flights
def test_rotation_folds_recover_the_planted_model_on_every_fold():
    """Noise-free flights of the planted rotor-drag model, each with its own balance point: every
    fold (two flights fitted, by downdating the three flights' sums) gives the planted torque
    gain and, within 2 %, the coefficients of a fit from scratch on those two flights (the fold
    keeps the three flights' robust weights)."""
    offsets = ([300.0, -300.0, 300.0, -300.0], [-400.0, 200.0, -100.0, 300.0], [600.0, -200.0, -600.0, 200.0])
    logs = [_balanced_flight(seed, off) for seed, off in zip((11, 12, 13), offsets)]
    cand = {"terms": DRAG_TERMS, "balance_weight_s": 1.0}
    assert downdatable(cand) and not downdatable({"method": "multistep"})
    assert not downdatable({"terms": ("damping", "attitude")})
    folds = rotation_folds(logs, LAYOUT, cand, window_s=0.05, rad_s_per_rpm=CRAZYFLIE_RAD_S_PER_ERPM)
    assert set(folds) == {log.name for log in logs}
    for name, m in folds.items():
        train = [log for log in logs if log.name != name]
        scratch = fit_rotation(train, LAYOUT, terms=DRAG_TERMS, balance_weight_s=1.0)
        assert m.flight_trims.shape == (2, 3)
        np.testing.assert_allclose(m.balance_prior, scratch.balance_prior, rtol=1e-12)
        for k in range(3):
            assert m.coef[k][0] == pytest.approx(DRAG_COEF[k][0], rel=0.05), (name, k)   # the torque gain
            np.testing.assert_allclose(m.coef[k], scratch.coef[k], rtol=0.02)
        np.testing.assert_allclose(m.flight_trims, scratch.flight_trims, atol=0.01)   # each trim to its own flight


def test_translation_folds_hold_each_flight_out():
    rng = np.random.default_rng(4)
    logs = [_decaying_flight(s, [4.0, 8.0, 1.0], n=400, name=f"f{s}") for s in (1, 2, 3)]
    logs = [StateLog(log.name, log.t_s, log.state, 90000.0 + 2000.0 * rng.standard_normal(log.rpm.shape), log.dt_s)
            for log in logs]
    rows = [translation_rows(log, delay_steps=0, rad_s_per_rpm=0.01) for log in logs]
    folds = translation_folds(rows, [log.name for log in logs], delay_steps=0, rad_s_per_rpm=0.01)
    assert set(folds) == {"f1", "f2", "f3"} and all(isinstance(t, TranslationModel) for t in folds.values())
    for name, t in folds.items():     # one step with the all-flights weights: close to a refit
        ref = fit_translation([log for log in logs if log.name != name], rad_s_per_rpm=0.01)
        assert t.k_thrust == pytest.approx(ref.k_thrust, rel=0.05) and t.k_thrust >= 0 and np.all(t.drag >= 0)


def test_damping_folds_are_the_fits_on_the_other_flights():
    logs = [_decaying_flight(s, c, name=f"f{s}") for s, c in ((1, [4.0, 8.0, 1.0]), (2, [2.0, 8.0, 1.0]),
                                                             (3, [4.0, 16.0, 0.5]))]
    folds = damping_folds(logs)
    for name, c in folds.items():
        np.testing.assert_array_equal(c, fit_damping([log for log in logs if log.name != name]))
