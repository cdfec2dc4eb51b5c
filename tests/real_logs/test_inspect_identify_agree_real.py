"""inspect and identify agree on every shared real log (issue 29, item 2): the fitness block of
``droneid inspect`` is the verdict identify reaches (the same prior resolution, the same
:func:`droneid.dataset.suitability.prior_fitness`), and its sample count is the number of rows identify's
dataset builder makes, within 5 %."""
from __future__ import annotations

import sys

import pytest

from droneid.dataset.builder import DatasetBuilder
from droneid.errors import DroneIdError
from droneid.dataset.suitability import check_prior_data, fitness_by_prior, usable_signals
from droneid.core.targets import targets_for
from parsers import read_flight
from priors.registry import prior_for

from conftest import ROOT, real_log

sys.path.insert(0, str(ROOT / "tests" / "golden"))
from regenerate import LOGS  # noqa: E402  (the shared real logs and their reader options)

pytestmark = pytest.mark.real_logs

TS = 0.05
#: every shared real log (the goldens' list, plus the other Crazyflie runs and Motive bodies)
CASES = [*LOGS.items(), *((f"mocap/crazyflie_nanodrone/square_run{i}.csv", {}) for i in range(2, 6)),
         *((f"mocap/crazyflie_nanodrone/melon_run{i}.csv", {}) for i in (1, 4)),
         *(("mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv", {"body": b}) for b in ("device03", "device05"))]


@pytest.mark.parametrize("rel, opts", CASES, ids=[f"{r}{o.get('body', '')}" for r, o in CASES])
def test_inspect_and_identify_agree(rel, opts):
    f = read_flight(real_log(rel), **opts)
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
