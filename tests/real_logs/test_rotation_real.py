"""The rotational model on the shared Crazyflie flights (issue 28): chosen per body axis by blocked
validation on the five squares only; the melon runs are test flights, scored after the choice.

What was measured (docs/use-the-model.md): on the held-out squares the torque model is three
times better than holding the rates when pooled (the corners, where the controller stops the
rotation), but in the calmer half of the windows it is worse than the rung below, on every
square: the ladder's rule (droneid.fitting.decide's sign-flip test over the 20 (square, regime) cells,
Holm over the 7 axis-rung steps at α = 0.01) refuses it. Every axis takes the rate decay, which
beats holding the rates on every square in every regime on roll and pitch, and in 19 of 20 cells
on yaw (it loses the calmest quarter of square 1). On the melon runs that model is below holding
the rates in velocity, attitude and body-rate SimErr and equal in position.

The attitude spring (the controller pulling the vehicle back to level; opt-in, ``rungs=RUNGS``:
it models the controller and a level setpoint, not the airframe) would be taken for roll and
pitch on the squares; on the melon runs, which hold a tilt for long stretches, it is worse than
holding the rates in body-rate and attitude SimErr.
"""
from __future__ import annotations

import numpy as np
import pytest

from droneid.simulation.openloop import IdentifiedVehicle, flight_state_logs, open_loop
from droneid.rotation.model import fit_translation
from droneid.rotation.choice import RUNGS, HeldRates, select_rotation
from parsers import read_flight

from conftest import real_log

pytestmark = pytest.mark.real_logs
CF = "mocap/crazyflie_nanodrone/"
SQUARES = [f"square_run{i}" for i in range(1, 6)]


def _flights(names):
    """Airborne stretches cut at gaps and glitches, each named by its flight (one validation block
    each), as identify and predict --open-loop read them."""
    return flight_state_logs([read_flight(real_log(CF + name + ".csv")) for name in names])


@pytest.fixture(scope="module")
def squares():
    return _flights(SQUARES)


@pytest.fixture(scope="module")
def choice(squares):
    return select_rotation(squares)


@pytest.mark.slow   # about 5 s: 5 folds x (held, decay, torque candidate)
def test_the_choice_sees_the_squares_only_and_refuses_the_torque_model_that_fails_in_calm_flight(choice):
    for step in choice.ladder:
        assert step["flights"] == SQUARES and step["family_size"] == 7 and step["alpha"] == 0.01
        assert all(st["cells"] == 20 for st in step["steps"])
    torque_rows = [r for r in choice.table if "terms" in r]
    for k in (0, 1):
        # pooled over the held-out squares the torque model is far better than the rates held ...
        assert min(r["rates_axis_simerr"][k] for r in torque_rows) < 0.5 * choice.held["rates_axis_simerr"][k]
        torque = [s for s in choice.ladder[k]["steps"] if s["rung"] == "torque"][0]
        # ... because it wins the hardest quarter of the windows on every square, while it loses
        # the calmest quarter on every square: it is not taken
        assert all(w[-1] for w in torque["wins"]) and not any(w[0] for w in torque["wins"])
        assert not torque["taken"] and choice.axis_choice[k] != "torque"
        assert torque["p_value"] > 0.5 and torque["effect_pct"] > 30      # far better pooled, not cell by cell
        # the rate decay beats holding the rates on every square in every regime
        decay = [s for s in choice.ladder[k]["steps"] if s["rung"] == "damping"][0]
        assert decay["taken"] and all(all(w) for w in decay["wins"]) and decay["p_value"] < decay["threshold"]
    assert not any(s["rung"] == "attitude" for step in choice.ladder for s in step["steps"])   # opt-in only
    yaw = choice.ladder[2]["steps"][0]
    assert yaw["rung"] == "damping" and yaw["taken"] and sum(not w for row in yaw["wins"] for w in row) == 1
    # the rotors' spin-up reaction on top of yaw's decay (issue 37.4) wins most cells, consistently
    # enough for the sign-flip test, but lowers yaw's pooled SimErr by less than the 1 % minimum
    spin = [s for s in choice.ladder[2]["steps"] if s["rung"] == "spinup"][0]
    assert spin["against"] == "damping" and spin["p_value"] < spin["threshold"]
    assert 0.0 < spin["effect_pct"] < 1.0 and not spin["taken"]
    assert choice.axis_choice == ("damping", "damping", "damping")
    row = choice.table[choice.chosen]
    assert row["method"] == "per-axis"
    for k, rung in enumerate(choice.axis_choice):
        if rung == "held":
            assert row["rates_axis_simerr"][k] == pytest.approx(choice.held["rates_axis_simerr"][k], rel=1e-9)
        else:
            assert row["rates_axis_simerr"][k] < choice.held["rates_axis_simerr"][k], k
    assert row["attitude_simerr"] < choice.held["attitude_simerr"]


@pytest.mark.slow   # about 15 s: every start of both melon runs, twice
def test_on_the_melon_runs_the_chosen_model_is_scored_against_holding_the_rates(choice, squares):
    """As measured (squares -> melon, docs/use-the-model.md says so: update both together): with
    identify's final v̇ models the rate decay on every axis lowers the body-rate SimErr (22.8 vs
    25.6 rad/s) and the attitude's (4.33 vs 4.53 rad); here, with a simpler translation, position
    stays within 2 %."""
    melon = _flights(["melon_run1", "melon_run4"])
    tr = fit_translation(squares, delay_steps=3)
    res = open_loop({"held": IdentifiedVehicle(tr, HeldRates()), "chosen": IdentifiedVehicle(tr, choice.model)}, melon)
    chosen, held = res["chosen"], res["held"]
    assert chosen.simerr["rates"] < 0.95 * held.simerr["rates"]
    assert chosen.simerr["attitude"] < held.simerr["attitude"]
    assert chosen.simerr["velocity"] < held.simerr["velocity"]
    assert chosen.simerr["position"] == pytest.approx(held.simerr["position"], rel=0.02)
    assert chosen.at(50)["rates"] < 0.9 * held.at(50)["rates"]


@pytest.mark.slow   # about 5 s
def test_the_opt_in_attitude_spring_is_taken_on_the_squares(squares):
    """With the controller's spring on the ladder (rungs=RUNGS) the squares take it for roll and
    pitch: every square in every regime. It is not a default rung: it models the controller's
    level setpoint, which the melon runs do not hold."""
    choice = select_rotation(squares, rungs=RUNGS)
    assert choice.axis_choice[:2] == ("attitude", "attitude")
    for k in (0, 1):
        spring = [s for s in choice.ladder[k]["steps"] if s["rung"] == "attitude"][0]
        assert spring["taken"] and all(all(w) for w in spring["wins"])


@pytest.mark.slow   # about 3 s: one torque fit on the squares
def test_the_refused_torque_model_turns_the_right_way_under_differential_thrust(squares):
    """The torque candidate the ladder refuses (issue 37.4) still has the layout's signs: +1 %
    thrust on the left rotors (M3, M4, left of the centre) rolls the vehicle right wing down
    (+ω̇x, FLU), on the front rotors (M1, M4) lifts the nose (−ω̇y: positive pitch is nose down).
    The chosen model has no torque term, so it does not turn at all (NOT STEERABLE)."""
    from droneid.rotation.model import fit_rotation
    from droneid.rotation.choice import DEFAULT_CANDIDATES
    torque = fit_rotation(squares, "crazyflie_x", **DEFAULT_CANDIDATES[0])
    s0 = np.full((1, 4), 3.0)                         # (ω/1000 rad/s)² near the Crazyflie's hover

    def turn(motors, model):
        s = s0.copy()
        s[0, motors] *= 1.01                           # thrust ∝ ω²: +1 % thrust
        zero = np.zeros((1, 3))
        return (model.ang_accel_from(zero, s, np.zeros((1, 4)), zero) - model.ang_accel_from(zero, s0, np.zeros((1, 4)), zero))[0]

    left, front = turn([2, 3], torque), turn([0, 3], torque)
    assert left[0] > 0.1 and abs(left[1]) < 0.1 * left[0]      # rad/s²: a roll, not a pitch
    assert front[1] < -0.1 and abs(front[0]) < 0.1 * -front[1]
    chosen = select_rotation(squares).model
    assert np.all(turn([2, 3], chosen) == 0.0) and chosen.unsteerable_axes() == ("roll", "pitch", "yaw")


@pytest.mark.slow   # about 5 s
def test_torque_gains_read_at_each_flights_alignment_and_band_hold_on_the_melon_runs(squares):
    """The torque rung's gains as vehicle constants (droneid.rotation.gains): measured 2026-11-28,
    roll 53.5 [49.7, 58.8], pitch 47.5 [43.4, 55.1] rad/s² per unit over the five squares, which
    differ by 6-9 % (NOT constant by the test); the melon runs' own (51-53) hold. Read without the
    band and the alignment, melon's came out 13.6-16.8: the slow part of the motor differences is
    the controller holding moments the model lacks."""
    from droneid.rotation.choice import DEFAULT_CANDIDATES
    from droneid.rotation.gains import check_gains, torque_gains
    from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM
    from priors.torque import get_layout
    g = torque_gains(squares, get_layout("crazyflie_x"), DEFAULT_CANDIDATES[0], rad_s_per_rpm=CRAZYFLIE_RAD_S_PER_ERPM,
                     unit="rad/s²")
    for axis in ("roll", "pitch"):
        v, lo, hi = g.gains[axis]
        assert 40 < lo < v < hi < 65, (axis, g.gains[axis])
        assert len(g.constancy[axis].per_unit) == 5
    assert set(g.conditions) == set(SQUARES) and all(0 <= a <= 0.06 for a, _ in g.conditions.values())
    tested = check_gains(g, _flights(["melon_run1", "melon_run4"])).tested
    assert set(tested) == {"melon_run1", "melon_run4"}
    for per in tested.values():
        assert per["roll"][4] is True and per["pitch"][4] is True, per
        assert 40 < per["roll"][0] < 65
