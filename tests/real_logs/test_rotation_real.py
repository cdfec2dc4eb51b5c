"""The rotational model on the shared Crazyflie squares (issue 28): chosen by blocked validation
on the training flights only (the melon runs are test flights and take no part here)."""
from __future__ import annotations

import pytest

from droneid.dataset_builder import in_flight_intervals
from droneid.openloop import state_log
from droneid.rotation_choice import select_rotation
from parsers import read_flight

from conftest import real_log

pytestmark = pytest.mark.real_logs
CF = "mocap/crazyflie_nanodrone/"


@pytest.mark.slow   # about 25 s: 5 folds x 6 candidates
def test_rotation_chosen_on_the_squares_beats_holding_the_rates_and_has_physical_signs():
    logs = []
    for i in range(1, 6):
        f = read_flight(real_log(CF + f"square_run{i}.csv"))
        logs += [state_log(f.between(a, b)) for a, b in in_flight_intervals(f)[0] if b - a > 0.6]
    choice = select_rotation(logs)
    assert choice.beats_held
    row = choice.table[choice.chosen]
    # held-out squares: the body rates and the attitude both at least a third better than held
    assert row["rates_simerr"] < 2.0 / 3.0 * choice.held["rates_simerr"]
    assert row["attitude_simerr"] < 2.0 / 3.0 * choice.held["attitude_simerr"]
    for k, (m, h) in enumerate(zip(row["rates_axis_simerr"], choice.held["rates_axis_simerr"])):
        assert m < h, k                          # roll, pitch and yaw each beat holding their rate
    m = choice.model
    assert "rotor_drag" in m.terms
    for k in (0, 1):
        drag = m.columns(k).index("rotor_drag")
        assert m.coef[k][0] > 0                  # torque along the layout's pattern
        assert m.coef[k][drag] > 0               # the rotor drag moment opposes the body velocity
    # the balance point: the moment's ratio to the torque gain is the same on roll and pitch
    # within a factor 2 (an arm-length symmetric frame)
    r = [m.coef[k][m.columns(k).index("rotor_drag")] / m.coef[k][0] for k in (0, 1)]
    assert 0.5 < r[0] / r[1] < 2.0
