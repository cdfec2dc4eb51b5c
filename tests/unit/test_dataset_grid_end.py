"""Regression: an interval ending a float ulp before a grid point must not yield a NaN sample.

Found by identify on the shipped square tlog (in-flight interval ends at 12.799999999999999 s,
the grid's tolerance put its last point at 12.8 s, past the data: the forward differentiator
then refused the NaN).
"""
from __future__ import annotations

import pytest

from droneid.dataset.builder import DatasetBuilder
from droneid.simulation.simulator import simulate


@pytest.mark.parametrize("method", ["forward", "savgol"])
@pytest.mark.parametrize("duration_s", [12.6, 12.8])
def test_interval_end_just_below_a_grid_point(duration_s, method):
    f = simulate(path="square", duration_s=duration_s, seed=12).flight
    ds = DatasetBuilder(method=method).build([f], target="vx_dot", inputs=("vx", "pitch", "roll", "yaw"))
    assert len(ds) >= int(duration_s / 0.05) - 2
