"""inspect and identify agree on every shared real log (issue 29, item 2): the fitness block of
``droneid inspect`` is the verdict identify reaches (the same prior resolution, the same
:func:`droneid.fitness.prior_fitness`), and its sample count is the number of rows identify's
dataset builder makes, within 5 %."""
from __future__ import annotations

import pytest

from droneid.dataset_builder import DatasetBuilder
from droneid.errors import DroneIdError
from droneid.fitness import check_prior_data, fitness_by_prior, usable_signals
from droneid.targets import targets_for
from parsers import read_flight
from priors.models import prior_for

from conftest import real_log

pytestmark = pytest.mark.real_logs

LOGS = {
    "ardupilot/copter33_quad_log171.bin": {},
    "ardupilot/copter462_quad_first80k.bin": {},
    "mavlink/copter357_quad_mission1.tlog": {},
    "mavlink/copter34_quad_bench_battery.tlog": {},
    "px4/vtol_short_hop.ulg": {},
    "px4/quad_fmuv5_ground.ulg": {},
    "px4/x500_sitl_events.ulg": {},
    "mcap/sportcub_fixedwing_qualisys.mcap": {},
    "mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv": {"body": "device02"},
    "mocap/crazyflie_nanodrone/square_run1.csv": {},
    "mocap/crazyflie_nanodrone/melon_run1.csv": {},
}
TS = 0.05


@pytest.mark.parametrize("rel", sorted(LOGS))
def test_inspect_and_identify_agree(rel):
    f = read_flight(real_log(rel), **LOGS[rel])
    shown = fitness_by_prior([f], TS)
    for spec in ("tilt-drag", "rotor-thrust"):
        got = shown[spec]
        try:
            prior, _ = prior_for(spec, usable_signals([f], TS))        # as identify resolves --prior
        except DroneIdError:
            assert not got["ok"]
            continue
        targets = targets_for(prior)
        try:
            check_prior_data([f], prior, targets, TS)                # identify's gate
            refused = False
        except DroneIdError as exc:
            refused = True
            assert got["problems"] and got["problems"][0] in str(exc)
        assert refused is (not got["ok"]), (spec, got["problems"])
        if refused:
            continue
        samples = got["flights"][0]["samples"]
        for t in targets:
            n = len(DatasetBuilder(ts=TS).build([f], target=t, inputs=prior.inputs(t), extras=()))
            assert abs(n - samples) <= 0.05 * n, (spec, t, n, samples)
