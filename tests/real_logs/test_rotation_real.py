"""The rotational model on the shared Crazyflie flights (issue 28): chosen per body axis by blocked
validation on the five squares only; the melon runs are test flights, scored after the choice.

What was measured (docs/use-the-model.md): on the held-out squares the torque model is three
times better than holding the rates when pooled (the corners, where the controller stops the
rotation), but in the calmer half of the windows it is worse than the rung below, on every
square: the ladder refuses it. Roll and pitch take the attitude spring (the controller pulling the
vehicle back to level), which beats the rung below on every square in every regime; yaw is held.
On the melon runs that model is below holding the rates in position and velocity SimErr and in
the body rates at 50 steps, but ABOVE it in body-rate and attitude SimErr: the squares' choice
does not transfer there in full, and the test says so.
"""
from __future__ import annotations

import pytest

from droneid.openloop import IdentifiedVehicle, flight_state_logs, open_loop
from droneid.rotation import fit_translation
from droneid.rotation_choice import _HeldRates, select_rotation
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


@pytest.mark.slow   # about 5 s: 5 folds x (held, decay, spring, 2 torque candidates)
def test_the_choice_sees_the_squares_only_and_refuses_the_torque_model_that_fails_in_calm_flight(choice):
    for step in choice.ladder:
        assert step["flights"] == SQUARES and step["level"] == 1 / 32
    torque_rows = [r for r in choice.table if "terms" in r]
    for k in (0, 1):
        # pooled over the held-out squares the torque model is far better than the rates held ...
        assert min(r["rates_axis_simerr"][k] for r in torque_rows) < 0.5 * choice.held["rates_axis_simerr"][k]
        torque = [s for s in choice.ladder[k]["steps"] if s["rung"] == "torque"][0]
        # ... because it wins the hardest quarter of the windows on every square, while it loses
        # the calmest quarter on every square: it is not taken
        assert all(w[-1] for w in torque["wins"]) and not any(w[0] for w in torque["wins"])
        assert not torque["taken"] and choice.axis_choice[k] != "torque"
        # the attitude spring beats the rung below on every square in every regime
        spring = [s for s in choice.ladder[k]["steps"] if s["rung"] == "attitude"][0]
        assert spring["taken"] and all(all(w) for w in spring["wins"])
    assert choice.axis_choice == ("attitude", "attitude", "held")
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
    """As measured: better in position SimErr and in the rates at 50 steps; worse in the rates'
    and the attitude's SimErr (docs/use-the-model.md says so: update both together)."""
    melon = _flights(["melon_run1", "melon_run4"])
    tr = fit_translation(squares, delay_steps=3)
    res = open_loop({"held": IdentifiedVehicle(tr, _HeldRates()), "chosen": IdentifiedVehicle(tr, choice.model)}, melon)
    chosen, held = res["chosen"], res["held"]
    assert chosen.simerr["position"] < 0.9 * held.simerr["position"]
    assert chosen.at(50)["rates"] < 0.8 * held.at(50)["rates"]
    for q in ("rates", "attitude"):
        assert chosen.simerr[q] > held.simerr[q], q
