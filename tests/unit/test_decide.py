"""The one decision rule (droneid.fitting.decide): accepts consistent held-out gains, rejects noise at
its stated family-wise level, Holm step-down over a family."""
from __future__ import annotations

import inspect

import numpy as np
import pytest

from droneid.fitting.decide import Decision, decide, decide_designs, decide_family, holm_threshold
from droneid.errors import ConfigError
from droneid.dataset.validation import block_ids


def _blocks(n=960, k=12):
    t = np.arange(n, dtype=float)
    return block_ids(t, np.zeros(n, int), k)


def test_consistent_gain_is_accepted_with_its_evidence():
    rng = np.random.default_rng(0)
    b = _blocks()
    e0 = rng.normal(0, 1.0, b.size)
    e1 = 0.8 * e0
    d = decide(e0, e1, b, alpha=0.01, family_size=9, what="wind")
    assert isinstance(d, Decision) and d.accepted
    assert d.n_blocks == 12 and d.blocks_better == 12 and d.p_value == pytest.approx(2.0 ** -12)
    assert d.threshold == pytest.approx(0.01 / 9)
    assert d.effect_pct == pytest.approx(20.0, abs=1e-9)
    assert d.evidence.startswith("wind: ") and "accepted" in d.evidence
    with pytest.raises(AttributeError):
        d.accepted = False                     # frozen


def test_half_the_blocks_worse_is_rejected_and_says_why():
    rng = np.random.default_rng(1)
    b = _blocks()
    e0 = rng.normal(0, 1.0, b.size)
    scale = np.where(b < 6, 0.45, 1.03)          # a big gain in half the blocks, a loss elsewhere
    d = decide(e0, e0 * scale, b, alpha=0.01)
    assert d.effect_pct > 15 and not d.accepted
    assert any("block test" in r for r in d.reasons) and "rejected" in d.evidence


def test_tiny_but_consistent_gain_fails_the_size_rule():
    rng = np.random.default_rng(2)
    b = _blocks()
    e0 = rng.normal(0, 1.0, b.size)
    d = decide(e0, 0.998 * e0, b, min_effect_pct=1.0)
    assert d.p_value < 1e-3 and not d.accepted and "RMSE falls by 0.20 %" in d.reasons[0]


def test_too_few_blocks_for_the_threshold_is_said():
    rng = np.random.default_rng(5)
    b = _blocks(800, 8)
    e0 = rng.normal(0, 1.0, b.size)
    d = decide(e0, 0.5 * e0, b, alpha=0.01, family_size=9)
    assert not d.accepted and d.p_value == pytest.approx(2.0 ** -8)
    assert any("use more blocks" in r for r in d.reasons)


def test_gain_concentrated_in_a_few_blocks_passes():
    """A large gain in 6 of 24 blocks and a small one elsewhere (ground effect near the ground):
    every block better, so the sign-flip p is tiny although a t-test would be weak."""
    rng = np.random.default_rng(6)
    b = _blocks(2400, 24)
    e0 = rng.normal(0, 1.0, b.size)
    e1 = e0 * np.where(b < 6, 0.3, 0.995)
    d = decide(e0, e1, b, alpha=0.01, family_size=15)
    assert d.accepted and d.p_value < 1e-4 and d.statistic < 4


def test_rule_has_no_test_flight_input():
    for f in (decide, decide_family, decide_designs):
        assert not any("test" in p for p in inspect.signature(f).parameters)


@pytest.mark.slow
def test_null_rejection_rate_is_at_most_alpha():
    """Calibration: an irrelevant regressor added to a least-squares model (residuals correlated
    in time, as on flights) is accepted in at most alpha of the trials (plus Monte-Carlo slack)."""
    rng = np.random.default_rng(3)
    n, trials, alpha = 480, 300, 0.05
    b = _blocks(n, 12)
    acc = 0
    for _ in range(trials):
        x = np.cumsum(rng.normal(size=n)) / 10          # slow, time-correlated signals
        z = np.cumsum(rng.normal(size=n)) / 10
        noise = np.convolve(rng.normal(size=n + 9), np.ones(10) / 10, "valid")   # coloured noise
        y = 0.5 * x + noise
        A0 = np.column_stack([x, np.ones(n)])
        A1 = np.column_stack([x, z, np.ones(n)])
        acc += decide_designs(A0, A1, y, b, alpha=alpha, min_effect_pct=0.0).accepted
    assert acc / trials <= alpha + 0.03, acc


def test_holm_thresholds_and_step_down():
    assert holm_threshold(0.01, 5, 1) == pytest.approx(0.002)
    assert holm_threshold(0.01, 5, 5) == pytest.approx(0.01)
    with pytest.raises(ConfigError, match="rank"):
        holm_threshold(0.01, 3, 4)
    rng = np.random.default_rng(4)
    b = _blocks()
    e0 = rng.normal(0, 1, b.size)
    cands = {"strong": 0.7 * e0, "weak": e0 * np.where(b % 2 == 0, 0.97, 1.005),
             "none": e0 + rng.normal(0, 0.05, b.size)}
    out = decide_family(e0, cands, b, alpha=0.01, min_effect_pct=0.0)
    assert list(out) == list(cands)
    assert out["strong"].accepted and out["strong"].rank == 1
    assert out["strong"].threshold == pytest.approx(0.01 / 3)
    assert not out["none"].accepted
    assert {d.rank for d in out.values()} == {1, 2, 3}


def test_bad_input_raises_config_error():
    b = _blocks(30, 3)
    with pytest.raises(ConfigError, match="same length"):
        decide(np.zeros(30), np.zeros(29), b)
    with pytest.raises(ConfigError, match="at least 3 validation blocks"):
        decide(np.ones(30), np.ones(30), np.zeros(30))


def test_one_block_much_worse_does_not_outweigh_fifteen_that_halve_the_error():
    """A constant wind offset halves the held-out error in 15 blocks; in one the gust cancels the
    mean wind locally and the offset triples the error there. The block statistic is the log
    ratio, so that block weighs ln 3 against 15 × ln 2 (the relative drop (mse0 − mse1)/mse0 gave
    it −2 against 15 × 0.5, and p = 0.03)."""
    b = _blocks(1600, 16)
    e0 = np.random.default_rng(3).normal(0, 1.0, b.size)
    e1 = e0 * np.where(b == 4, np.sqrt(3.0), np.sqrt(0.5))
    d = decide(e0, e1, b, alpha=0.01, family_size=13)
    assert d.accepted and d.blocks_better == 15 and d.p_value < 0.01 / 13
    assert d.block_differences[4] == pytest.approx(-np.log(3.0), rel=1e-9)


def test_block_statistic_is_antisymmetric_in_the_two_models():
    """Under "the candidate does not help" the two models are exchangeable, and the sign-flip test
    assumes each block statistic is as likely positive as negative: swapping the models must
    negate it exactly (the relative drop did not: +0.5 one way, −1 the other)."""
    rng = np.random.default_rng(4)
    b = _blocks()
    e0, e1 = rng.normal(0, 1.0, b.size), rng.normal(0, 1.2, b.size)
    fwd, back = decide(e0, e1, b), decide(e1, e0, b)
    assert np.allclose(fwd.block_differences, -np.asarray(back.block_differences))


def test_the_sign_flip_p_is_that_of_fresh_draws_every_time():
    # the random sign patterns are drawn once per block count and reused (speed); every p must
    # be the one the fixed-seed draws give, call after call and for any data
    from droneid.fitting.decide import N_FLIPS, paired_block_test

    def fresh_p(d):
        rng = np.random.default_rng(20251125)
        obs = float(np.sum(d)) * (1 - 1e-12)
        hits = sum(int(np.sum(rng.choice((-1.0, 1.0), size=(10_000, d.size)) @ d >= obs))
                   for _ in range(N_FLIPS // 10_000))
        return (1 + hits) / (1 + N_FLIPS)

    rng = np.random.default_rng(4)
    for b, shift in ((20, 0.0), (20, 0.3), (31, 0.1), (20, -0.2)):
        d = rng.normal(shift, 1.0, b)
        assert paired_block_test(d)[1] == fresh_p(d)


def test_a_pooled_fall_that_most_blocks_contradict_says_so():
    """x500 offset note: 'CV RMSE 0.9208 -> 0.883 (-4.1 %)' beside 'p = 1', 11/36 blocks better."""
    rng = np.random.default_rng(3)
    b = _blocks()
    e0 = rng.normal(0, 1.0, b.size) * np.where(b < 2, 4.0, 1.0)   # two loud blocks dominate the pooled RMSE
    scale = np.where(b < 2, 0.8, 1.05)                             # they improve, every other block worsens
    d = decide(e0, e0 * scale, b, alpha=0.01)
    assert d.effect_pct > 0 and d.statistic < 0 and not d.accepted
    assert "pooled over the rows; the typical block gets worse" in d.evidence
    ok = decide(e0, 0.8 * e0, b, alpha=0.01)
    assert "pooled over the rows" not in ok.evidence


def test_decide_units_on_simulation_errors_pools_the_error_itself():
    """Per-unit SimErr (not squared residuals): the effect is the drop of the window-weighted mean
    SimErr, the units are cells, and the test is the same sign-flip test on the log ratios."""
    from droneid.fitting.decide import decide_units
    m0 = np.array([10.0, 20.0, 40.0, 80.0] * 4)
    m1 = 0.5 * m0
    d = decide_units(m0, m1, np.full(16, 30), alpha=0.01, family_size=6, loss="simerr", what="roll damping")
    assert d.accepted and d.effect_pct == pytest.approx(50.0) and d.rmse_without == pytest.approx(37.5)
    assert d.p_value == pytest.approx(1 / (1 + 50_000)) and d.n_blocks == 16
    assert "SimErr 37.5 -> 18.75" in d.evidence and "16/16 cells better" in d.evidence
    # the same figures read as mean squared errors: the effect is on their root
    assert decide_units(m0, m1, np.full(16, 30), loss="mse").effect_pct == pytest.approx(100 * (1 - 0.5 ** 0.5))
    with pytest.raises(ConfigError, match="'loss' parameter"):
        decide_units(m0, m1, loss="mae")
    with pytest.raises(ConfigError, match="at least 3 validation cells"):
        decide_units(m0[:2], m1[:2], loss="simerr")


def test_holm_step_down_is_the_family_rule_over_any_decisions():
    from droneid.fitting.decide import decide_units, holm_step_down
    base = np.array([1.0, 2.0, 3.0, 4.0] * 3)
    gains = {"a": 0.5, "b": 0.9, "c": 1.0}          # consistent, consistent, none
    out = holm_step_down(lambda n, k: decide_units(base, gains[n] * base, alpha=0.01, family_size=3, rank=k,
                                                   loss="simerr"), list(gains))
    assert [out[n].accepted for n in "abc"] == [True, True, False]
    assert sorted(out[n].rank for n in "abc") == [1, 2, 3]


def test_a_p_on_its_threshold_is_printed_so_that_it_can_be_told_from_it():
    """log171's battery compensation had p = 0.0099998 (499 of 50 000 sign patterns) against
    0.01, printed "0.01 < 0.01": a reader could not tell why it passed. The p now carries the
    digits that tell it from the threshold; a p away from it keeps two."""
    from droneid.fitting.decide import p_text
    assert p_text(0.0099998, 0.01) == ("0.0099998", "0.01")
    assert p_text(0.010239795, 0.01) == ("0.0102", "0.01")
    assert p_text(0.00046, 0.00067) == ("0.00046", "0.00067")
    assert p_text(0.5, 0.01) == ("0.5", "0.01")
    assert p_text(0.01, 0.01) == ("0.01", "0.01")
    # a Holm threshold that two digits do not show: both get the digits, in the right order
    assert p_text(166 / 50000, 0.01 / 3) == ("0.00332", "0.00333")
    assert p_text(0.00126, 0.00125) == ("0.00126", "0.00125")
