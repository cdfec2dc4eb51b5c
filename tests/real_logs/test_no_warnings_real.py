"""No Python warning reaches the user (issue 29, item 3): ``droneid inspect`` on every shared real
log, in a subprocess with warnings turned into errors (``python -W error``). Before the fix,
``inspect vtol_short_hop.ulg`` printed "dataset_builder.py:201: RuntimeWarning: Mean of empty
slice"."""
from __future__ import annotations

import subprocess
import sys

import pytest

from conftest import ROOT, real_log

pytestmark = pytest.mark.real_logs

#: every shared real log, with the options it needs (a multi-body Motive file needs --body)
LOGS = {
    "ardupilot/copter33_quad_log171.bin": [],
    "ardupilot/copter462_quad_first80k.bin": [],
    "mavlink/copter357_quad_mission1.tlog": [],
    "mavlink/copter34_quad_bench_battery.tlog": [],
    "px4/vtol_short_hop.ulg": [],
    "px4/quad_fmuv5_ground.ulg": [],
    "px4/x500_sitl_events.ulg": [],
    "px4/octo_px4tools_01_07_59.px4log": [],
    "mcap/sportcub_fixedwing_qualisys.mcap": [],
    "mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv": ["--body", "device02"],
    **{f"mocap/crazyflie_nanodrone/square_run{i}.csv": [] for i in range(1, 6)},
    **{f"mocap/crazyflie_nanodrone/melon_run{i}.csv": [] for i in (1, 4)},
}


def _inspect(path, *args):
    return subprocess.run([sys.executable, "-W", "error", "-m", "droneid", "inspect", str(path), *args],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize("rel", sorted(LOGS))
def test_inspect_with_warnings_as_errors(rel):
    path = real_log(rel)
    for extra in ([], ["--json"]):
        r = _inspect(path, *LOGS[rel], *extra)
        assert r.returncode == 0, r.stderr[-2000:]
        assert "Traceback" not in r.stderr and "Warning:" not in r.stderr, r.stderr[-2000:]
        assert r.stdout.strip()


def test_every_shared_log_is_listed(real_logs):
    """A log added to the shared folder is added here too (the test covers EVERY shared log)."""
    found = {p.relative_to(real_logs).as_posix() for p in real_logs.rglob("*")
             if p.is_file() and p.suffix.lower() in (".bin", ".tlog", ".ulg", ".px4log", ".mcap", ".csv")}
    assert found == set(LOGS)
