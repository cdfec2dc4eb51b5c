"""Physics-bounded estimates on real flights (issue 24): no rung of any ladder has negative drag
on the shared Crazyflie squares or on ArduCopter log171, every rung carries intervals, gravity is
never fitted, and log171's v̇z (negative drag, a quarter of gravity before) claims no win.

The physical ladder is built as identify builds it (plan on the training flights, then the
rungs); no SNGP run is needed, so the final model is the physical rung."""
import pytest

from conftest import real_log

pytestmark = [pytest.mark.real_logs, pytest.mark.slow]

CF = "mocap/crazyflie_nanodrone/"


def _ladders(train, test=None, quick=True):
    from droneid.identify.pipeline import IdentifyConfig, prepare_target, summarise_target
    from droneid.diagnosis.diagnose import plan_identification
    from parsers import read_flight
    train = [read_flight(str(p)) for p in train]
    test = [read_flight(str(p)) for p in test] if test else None
    cfg = IdentifyConfig.make(quick=quick)
    plan = plan_identification(train, cfg)
    return {t: summarise_target(prepare_target(train, test, t, cfg, plan), cfg, []) for t in plan.targets}


def _no_negative_drag(targets):
    for t, tr in targets.items():
        for r in tr.ladder[1:]:
            assert r.intervals, (t, r.name)
            for lab, c in r.terms.items():
                if "kD" in lab:
                    assert c >= 0.0, (t, r.name, lab, c)


@pytest.fixture(scope="module")
def squares():
    return _ladders([real_log(f"{CF}square_run{i}.csv") for i in range(1, 6)],
                    [real_log(f"{CF}melon_run{i}.csv") for i in (1, 4)])


def test_the_squares_have_no_negative_drag_and_free_fall_at_zero_thrust(squares):
    _no_negative_drag(squares)
    vz = squares["vz_dot"]
    for r in vz.ladder[1:]:
        assert r.intercept == pytest.approx(-9.81)       # gravity, never a free parameter
    lo, hi = vz.intervals["sum_rpm_sq_z"].low, vz.intervals["sum_rpm_sq_z"].high
    assert lo < hi and 0.9 < lo <= hi < 1.1                # hover-calibrated thrust scale, pinned down


def test_the_squares_verdicts_are_wins_on_the_melon_runs(squares):
    for t, tr in squares.items():
        assert tr.verdict_kind == "better", tr.verdict


def test_log171_has_no_negative_drag_and_its_vz_claims_no_win():
    targets = _ladders([real_log("ardupilot/copter33_quad_log171.bin")])
    _no_negative_drag(targets)
    assert targets["vz_dot"].verdict_kind != "better", targets["vz_dot"].verdict
