"""The tilt-drag prior against the real Crazyflie flights (moved from
tests/integration/test_dataset_cli.py): least squares on the five square runs gives a gravity
coefficient of order one and a drag coefficient that opposes the velocity."""
from __future__ import annotations

import pytest

from droneid.dataset.builder import DatasetBuilder

from _physics import tilt_drag_coefficients
from conftest import real_log

pytestmark = pytest.mark.real_logs


def test_crazyflie_gravity_coefficient_is_positive_and_of_order_one():
    from parsers import read_flight
    flights = [read_flight(real_log(f"mocap/crazyflie_nanodrone/square_run{i}.csv")) for i in range(1, 6)]
    # the dominant tilt term at yaw ≈ 0: pitch for vx_dot (cosψ tanθ/cosφ), roll for vy_dot (−cosψ tanφ)
    for target, k in (("vx_dot", 0), ("vy_dot", 1)):
        ds = DatasetBuilder().build(flights, target, extras=())
        assert len(ds) > 2000 and len(ds.sources) == 5
        beta = tilt_drag_coefficients(ds, target)
        assert 0.3 < beta[k] < 2.0, beta
        assert beta[2] > 0  # drag opposes velocity
