"""Every public real log under ../shared/real_logs reads with the signals its README lists, and
the converted data obey physics (skipped where the folder is absent)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from parsers import detect_format, read_flight

from _physics import tilt_drag_correlation
from conftest import real_log

pytestmark = pytest.mark.real_logs

CRAZYFLIE = [f"mocap/crazyflie_nanodrone/square_run{i}.csv" for i in range(1, 6)] + \
            [f"mocap/crazyflie_nanodrone/melon_run{i}.csv" for i in (1, 4)]

#: file -> (format, signals its README lists, as canonical names)
EXPECTED = {
    "ardupilot/copter33_quad_log171.bin": ("dataflash", ("roll", "pitch", "yaw", "vx", "vy", "vz", "ax", "wx",
                                                         "motor1", "motor4", "throttle", "battery_voltage")),
    "ardupilot/copter462_quad_first80k.bin": ("dataflash", ("roll", "vx", "x", "throttle", "battery_voltage",
                                                            "motor1", "ax")),
    "mavlink/copter357_quad_mission1.tlog": ("tlog", ("roll", "pitch", "yaw", "x", "vx", "lat", "lon", "ax",
                                                      "motor1", "throttle")),
    "mavlink/copter34_quad_bench_battery.tlog": ("tlog", ("roll", "battery_voltage")),
    "px4/vtol_short_hop.ulg": ("ulog", ("qw", "roll", "z", "vz", "ax", "motor1", "battery_voltage")),
    "px4/quad_fmuv5_ground.ulg": ("ulog", ("qw", "roll", "z", "ax", "motor1", "battery_voltage")),
    "px4/x500_sitl_events.ulg": ("ulog", ("qw", "roll", "x", "vx", "ax", "motor1", "throttle",
                                          "battery_voltage")),
    "px4/octo_px4tools_01_07_59.px4log": ("px4log", ("roll", "pitch", "yaw", "wx", "x", "vx", "vz", "ax",
                                                     *(f"motor{i}" for i in range(1, 9)), "throttle",
                                                     "battery_voltage", "lat")),
    "mcap/sportcub_fixedwing_qualisys.mcap": ("mcap", ("x", "y", "z", "qw", "roll", "vx", "rc1")),
    "mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv": ("motive_csv", ("x", "y", "z", "qw", "vx")),
    **{p: ("csv", ("x", "y", "z", "qw", "roll", "vx", "vy", "vz", "wx", "ax", "motor1", "throttle",
                   "battery_voltage")) for p in CRAZYFLIE},
}


@pytest.mark.parametrize("rel", sorted(EXPECTED))
def test_real_log_reads_with_its_signals(rel):
    path = real_log(rel)
    fmt, names = EXPECTED[rel]
    assert detect_format(path) == fmt
    kw = {"body": "device02"} if fmt == "motive_csv" else {}
    f = read_flight(path, **kw)
    assert f.provenance.format == fmt
    assert f.has(*names), sorted(set(names) - set(f.names))
    for s in f.signals.values():           # internal convention: seconds from the log start
        assert s.start_s >= 0 and np.all(np.diff(s.t) > 0) and np.isfinite(s.values).all()
    assert f.start_s < 1.0
    if f.has("qw"):
        q = np.column_stack([f[n].values for n in ("qw", "qx", "qy", "qz")])
        assert np.allclose(np.linalg.norm(q, axis=1), 1, atol=1e-6)


def test_copter33_attitude_and_ekf_velocity_over_240s_ending_in_a_crash():
    f = read_flight(real_log("ardupilot/copter33_quad_log171.bin"))
    assert f.provenance.firmware.startswith("APM:Copter V3.3")
    assert f.provenance.vehicle == "quad"
    for n in ("roll", "vx"):
        assert 235 < f[n].end_s - f[n].start_s < 250
        assert 9 < f[n].rate_hz < 11
    assert 45 < f["ax"].rate_hz < 55
    assert f["vx"].source.startswith("EKF1")
    crash = [e for e in f.events if e.kind == "crash"]
    assert crash and crash[0].t_s > f.duration_s - 30
    assert f.segments["in_flight"][-1][1] == pytest.approx(crash[0].t_s)
    # ThrOut 0..1000 normalised, CURR centivolts -> V, PWM -> 0..1
    assert 0.2 < np.median(f.between(*f.segments["in_flight"][0])["throttle"].values) < 0.9
    assert 10 < np.median(f["battery_voltage"].values) < 17.5
    assert f["motor1"].values.min() >= 0 and f["motor1"].values.max() <= 1
    # at rest before arming: accelerometer reads +g along body up (FLU)
    rest = f["az"].between(0, 50).values
    assert 9.3 < np.median(rest) < 10.3


def test_copter462_prefix_uses_new_names():
    f = read_flight(real_log("ardupilot/copter462_quad_first80k.bin"))
    assert "V4.6.2" in f.provenance.firmware
    assert f["vx"].source.startswith("XKF1") and f["battery_voltage"].source == "BAT.Volt"
    assert f["motor1"].source.startswith("RCOU.C1 (PWM 1120-1920 us (MOT_PWM_MIN/MAX)") and f["throttle"].source == "CTUN.ThO"
    assert f.duration_s == pytest.approx(0.4, abs=0.05)
    assert 9.3 < np.median(f["az"].values) < 10.3


def test_tlog_mission_vehicle_and_flights():
    f = read_flight(real_log("mavlink/copter357_quad_mission1.tlog"))
    assert "V3.5.7" in f.provenance.firmware
    assert 860 < f.duration_s < 870
    assert len(f.segments["armed"]) >= 5 and len(f.segments["in_flight"]) >= 5
    # the mission climbs to about 20 m
    assert 15 < f["z"].values.max() - f["z"].values.min() < 25
    # voltage reads 0 in this log: skipped and counted, not reported as 0 V
    assert "battery_voltage" not in f
    assert f.diagnostics.skipped["SYS_STATUS battery voltage unknown (0 or 65535)"] > 100


def test_tlog_bench_battery():
    f = read_flight(real_log("mavlink/copter34_quad_bench_battery.tlog"))
    assert f.segments["armed"] == ()
    assert np.median(f["battery_voltage"].values) == pytest.approx(11.6, abs=0.2)
    assert 19 < f.duration_s < 21


@pytest.mark.parametrize("rel", ["px4/vtol_short_hop.ulg", "px4/quad_fmuv5_ground.ulg", "px4/x500_sitl_events.ulg"])
def test_ulog_at_rest_gravity_and_segments(rel):
    f = read_flight(real_log(rel))
    assert f.segments["armed"] and "in_flight" in f.segments
    a0 = f.segments["armed"][0][0]
    rest = f["az"].between(0, a0 + 0.3).values if a0 > 0.5 else f["az"].values[:20]
    assert 9.0 < np.median(rest) < 10.6           # FLU: +g up at rest
    r = f["roll"].values
    assert np.median(np.abs(r[: max(5, len(r) // 10)])) < 0.2   # level on the ground


def test_vtol_rates():
    f = read_flight(real_log("px4/vtol_short_hop.ulg"))
    assert f.provenance.firmware == "PX4 v1.11.2 (8583f1da)"
    assert f.provenance.vehicle == "vtol on CUBEPILOT_CUBEORANGE"
    assert 190 < f["roll"].rate_hz < 210
    assert 95 < f["z"].rate_hz < 105
    # horizontal position is flagged invalid throughout: skipped and counted, not zeros
    assert "x" not in f and f.diagnostics.skipped["vehicle_local_position samples with xy_valid false"] > 600


def test_px4log_octocopter_as_its_readme_says():
    """The sdlog2 octocopter: 8 motors at 47 Hz, 70 s, up to 7 m and 5.4 m/s; time is the TIME
    records' StartTime, which is what pymavlink's own PX4 clock stamps every message with."""
    from pymavlink import DFReader
    path = real_log("px4/octo_px4tools_01_07_59.px4log")
    f = read_flight(path)
    assert f.provenance.vehicle_type == "multirotor" and "octorotor" in f.provenance.vehicle
    assert f.has(*(f"motor{i}" for i in range(1, 9))) and not f.has("motor9")
    assert 45 < f["motor1"].rate_hz < 50 and 78 < f["roll"].rate_hz < 84
    assert 69 < f.duration_s < 72
    assert 5 < f["z"].values.max() - f["z"].values.min() < 9           # climbs to about 7 m
    assert 4.5 < np.hypot(f["vx"].values, f["vy"].values).max() < 6.5
    assert 21 < np.median(f["battery_voltage"].values) < 25.2            # 6S
    assert 9.3 < np.median(f["az"].values) < 10.3                         # FLU: +g up
    log = DFReader.DFReader_binary(str(path), zero_time_base=True)
    stamps = []
    while (m := log.recv_match(type=["TIME", "ATT"])) is not None:    # its clock needs the TIMEs
        if m.get_type() == "ATT":
            stamps.append(m._timestamp)
    log.close()
    np.testing.assert_allclose(f["roll"].t, np.asarray(stamps) - stamps[0], atol=1e-6)


def test_mcap_pose_topic_frame_and_rate():
    f = read_flight(real_log("mcap/sportcub_fixedwing_qualisys.mcap"))
    assert f["x"].source.startswith("/cub1/pose")
    assert 99 < f["x"].rate_hz < 101
    assert 195 < f.duration_s < 200
    assert any("frame_id qualisys" in n for n in f.provenance.notes)
    assert any("derived from position" in n for n in f.provenance.notes)
    g = read_flight(real_log("mcap/sportcub_fixedwing_qualisys.mcap"), topics={"pose": "/cub1/pose"})
    assert len(g["x"]) == len(f["x"])


def test_motive_three_bodies():
    path = real_log("mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv")
    from droneid.errors import ConfigError
    with pytest.raises(ConfigError, match="device02, device03, device05"):
        read_flight(path)
    f = read_flight(path, body="device05")
    assert f.provenance.vehicle == "rigid body device05"
    assert np.median(np.diff(f["x"].t)) == pytest.approx(0.01)     # 100 Hz capture
    assert 95 < f["x"].rate_hz < 100    # gap-aware: occluded frames inside its bursts are missing


@pytest.mark.parametrize("rel", CRAZYFLIE)
def test_crazyflie_100hz_pose_and_velocity(rel):
    f = read_flight(real_log(rel))
    for n in ("x", "qw", "vx", "wx"):
        assert f[n].rate_hz == pytest.approx(100.0, rel=1e-3)
    assert f["vx"].source == "vx"                     # measured, not derived
    assert any("equal the quaternion's Z-Y-X Euler angles in rad" in n for n in f.provenance.notes)
    assert f.segments["in_flight"]
    assert 3.0 < np.median(f["battery_voltage"].values) < 4.3


# --------------------------------------------------------------------------- physics
#: real quadrotor flights with attitude and velocity -> (kwargs for the check, minimum corr)
PHYSICS = {
    "ardupilot/copter33_quad_log171.bin": ({}, 0.8),
    "mavlink/copter357_quad_mission1.tlog": ({"rate_hz": 1.0, "smooth_s": 0.0}, 0.3),  # 1 Hz telemetry
    "px4/x500_sitl_events.ulg": ({}, 0.4),                                            # SITL, not real
    "px4/octo_px4tools_01_07_59.px4log": ({}, 0.5),                                   # outdoors, GPS/EKF velocity
    **{p: ({}, 0.7) for p in CRAZYFLIE},
}
MEASURED: dict = {}


@pytest.mark.parametrize("rel", sorted(PHYSICS))
def test_horizontal_acceleration_follows_tilt(rel):
    """d/dt(vx, vy) correlates POSITIVELY with g(cosψ tanθ/cosφ + sinψ tanφ) and
    g(sinψ tanθ/cosφ − cosψ tanφ): a sign error in any frame conversion makes it negative."""
    f = read_flight(real_log(rel))
    kw, floor = PHYSICS[rel]
    cx, cy, n = tilt_drag_correlation(f, **kw)
    MEASURED[rel] = (cx, cy, n)
    assert n > 50
    assert cx > floor and cy > floor, (cx, cy)


def test_physics_check_catches_a_pitch_sign_flip():
    """The same check on a flight with pitch negated (the classic NED->ENU mistake) fails."""
    from droneid.logs.flight import Signal
    f = read_flight(real_log("mocap/crazyflie_nanodrone/square_run2.csv"))
    p = f["pitch"]
    bad = f.with_signals(Signal("pitch", p.t, -p.values, p.unit, p.source))
    cx, cy, _ = tilt_drag_correlation(bad)
    assert cx < 0.3 or cy < 0.3
    y = f["yaw"]
    bad = f.with_signals(Signal("yaw", y.t, np.pi / 2 - y.values, y.unit, y.source))  # NED yaw left in
    cx, cy, _ = tilt_drag_correlation(bad)
    assert cx < 0.3 or cy < 0.3
    r = f["roll"]
    bad = f.with_signals(Signal("roll", r.t, -r.values, r.unit, r.source))
    cx, cy, _ = tilt_drag_correlation(bad)
    assert cy < 0 and math.isfinite(cx)
