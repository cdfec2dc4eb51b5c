"""Rotor signals (issue 11) in the shared real logs (moved from tests/unit/test_rotor_signals.py):
``droneid inspect --json`` lists the motor outputs, speeds, throttle and battery voltage each log
records, in canonical units."""
from __future__ import annotations

import json

import pytest

from droneid.cli import main
from droneid.logs.flight import canonical_unit

from conftest import real_log

pytestmark = pytest.mark.real_logs

#: real logs that record motor data -> the rotor signals `inspect` must list
REAL_ROTOR = {
    "ardupilot/copter33_quad_log171.bin": ["motor1", "motor2", "motor3", "motor4", "throttle"],
    "ardupilot/copter462_quad_first80k.bin": ["motor1", "motor4", "throttle"],
    "mavlink/copter357_quad_mission1.tlog": ["motor1", "motor4", "throttle"],
    "mavlink/copter34_quad_bench_battery.tlog": ["motor1", "motor4", "battery_voltage"],
    "px4/x500_sitl_events.ulg": ["rpm1", "rpm2", "rpm3", "rpm4", "motor1", "motor4", "throttle"],
    "px4/quad_fmuv5_ground.ulg": ["motor1", "motor4"],
    "px4/vtol_short_hop.ulg": ["motor1", "motor8"],
    "px4/octo_px4tools_01_07_59.px4log": [f"motor{i}" for i in range(1, 9)] + ["throttle", "battery_voltage"],
    "mocap/crazyflie_nanodrone/square_run1.csv": ["rpm1", "rpm2", "rpm3", "rpm4", "motor1", "motor4",
                                                  "throttle", "battery_voltage"],
}


@pytest.mark.parametrize("rel", sorted(REAL_ROTOR))
def test_real_logs_list_rotor_signals(rel, capsys):
    path = real_log(rel)
    assert main(["inspect", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    sig = {s["name"]: s for s in out["signals"]}
    for name in REAL_ROTOR[rel]:
        assert name in sig, (rel, name)
        if sig[name]["unit"] == "erpm":       # electrical rpm (the Crazyflie's m*_erpm), said so
            assert name.startswith("rpm") and "electrical rpm" in sig[name]["source"]
        else:
            assert sig[name]["unit"] == canonical_unit(name)
        if name.startswith("motor"):
            assert "0..1" in sig[name]["source"], sig[name]["source"]
