"""MAVLink tlog reader on tlogs built with pymavlink's encoder: planted NED values must come out
ENU/FLU (a sign flip in any conversion fails here), vehicle sysid selection, damage counting."""
from __future__ import annotations

import math

import numpy as np
import pytest

from droneid.errors import LogFormatError
from parsers import detect_format, read_flight

from tlog_fixture import tlog_bytes

ARMED = 128 | 81


def _flight_msgs(n=20, sysid=1):
    msgs = []
    for i in range(n):
        t = 0.1 * i
        msgs.append(("heartbeat", t, dict(base_mode=ARMED if 5 <= i < 15 else 81, custom_mode=5), sysid))
        msgs.append(("attitude", t + 0.01, dict(time_boot_ms=i * 100, roll=0.1, pitch=0.2, yaw=0.0,
                                                rollspeed=0.01, pitchspeed=0.02, yawspeed=0.03), sysid))
        msgs.append(("local_position_ned", t + 0.02, dict(time_boot_ms=i * 100, x=1.0 * t, y=0.0, z=-2.0,
                                                          vx=1.0, vy=0.5, vz=-0.25), sysid))
        msgs.append(("raw_imu", t + 0.03, dict(time_usec=i * 100000, xacc=100, yacc=0, zacc=-1000,
                                               xgyro=10, ygyro=20, zgyro=30, xmag=0, ymag=0, zmag=0), sysid))
        msgs.append(("vfr_hud", t + 0.04, dict(airspeed=0, groundspeed=0, heading=0, throttle=55, alt=2,
                                               climb=0.25), sysid))
        msgs.append(("sys_status", t + 0.05, dict(onboard_control_sensors_present=0,
                                                  onboard_control_sensors_enabled=0,
                                                  onboard_control_sensors_health=0, load=0,
                                                  voltage_battery=11600, current_battery=1250,
                                                  battery_remaining=50, drop_rate_comm=0, errors_comm=0,
                                                  errors_count1=0, errors_count2=0, errors_count3=0,
                                                  errors_count4=0), sysid))
        msgs.append(("servo_output_raw", t + 0.06, dict(time_usec=i, port=0, servo1_raw=1500, servo2_raw=1000,
                                                        servo3_raw=2000, servo4_raw=1250, servo5_raw=0,
                                                        servo6_raw=0, servo7_raw=0, servo8_raw=0), sysid))
    return msgs


def test_planted_ned_values_come_out_enu_flu(tmp_path):
    p = tmp_path / "planted.tlog"
    p.write_bytes(tlog_bytes(_flight_msgs()))
    assert detect_format(p) == "tlog"
    f = read_flight(p)
    assert np.allclose(f["roll"].values, 0.1)
    assert np.allclose(f["pitch"].values, -0.2)              # NED nose-up 0.2 -> FLU pitch -0.2
    assert np.allclose(f["yaw"].values, math.pi / 2)          # heading north -> yaw +90 deg from east
    assert np.allclose(f["vx"].values, 0.5) and np.allclose(f["vy"].values, 1.0)   # east, north
    assert np.allclose(f["vz"].values, 0.25)                  # NED vz -0.25 (climbing) -> up +0.25
    assert np.allclose(f["z"].values, 2.0)
    assert np.allclose(f["az"].values, 9.80665, atol=1e-6)    # at rest: +g along body up
    assert np.allclose(f["ax"].values, 0.980665)
    assert np.allclose(f["wy"].values, -0.02) and np.allclose(f["wz"].values, -0.03)
    assert np.allclose(f["throttle"].values, 0.55)
    assert np.allclose(f["battery_voltage"].values, 11.6) and np.allclose(f["battery_current"].values, 12.5)
    assert np.allclose(f["motor1"].values, 0.5) and np.allclose(f["motor3"].values, 1.0)
    assert "motor5" not in f
    (a, b), = f.segments["armed"]
    assert a == pytest.approx(0.5) and b == pytest.approx(1.5)
    assert f["x"].start_s == pytest.approx(0.02)              # seconds from the first frame


def test_mavlink_v1_frames_too(tmp_path):
    p = tmp_path / "v1.tlog"
    p.write_bytes(tlog_bytes(_flight_msgs(5), v2=False))
    f = read_flight(p)
    assert np.allclose(f["pitch"].values, -0.2)


def test_vehicle_sysid_is_the_one_with_a_vehicle_heartbeat(tmp_path):
    msgs = _flight_msgs(10, sysid=7)
    # a GCS (type 6, autopilot 8) sending heartbeats and its own attitude-like noise
    msgs += [("heartbeat", 0.1 * i + 0.005, dict(type=6, autopilot=8), 255) for i in range(30)]
    msgs += [("attitude", 0.1 * i + 0.007, dict(time_boot_ms=0, roll=-1, pitch=-1, yaw=-1, rollspeed=0,
                                                 pitchspeed=0, yawspeed=0), 255) for i in range(10)]
    msgs.sort(key=lambda m: m[1])
    p = tmp_path / "multi.tlog"
    p.write_bytes(tlog_bytes(msgs))
    f = read_flight(p)
    assert np.allclose(f["roll"].values, 0.1)
    assert f.provenance.vehicle == "quadrotor"
    g = read_flight(p, sysid=255)
    assert np.allclose(g["roll"].values, -1)
    with pytest.raises(LogFormatError, match="system id 3"):
        read_flight(p, sysid=3)


def test_corrupt_frames_and_garbage_are_counted(tmp_path):
    data = bytearray(tlog_bytes(_flight_msgs()))
    # flip a payload byte of the first frame (bad CRC) and insert garbage in the middle
    data[8 + 10 + 1] ^= 0xFF
    mid = len(data) // 2
    data[mid:mid] = b"\x00garbage\x01\x02"
    p = tmp_path / "damaged.tlog"
    p.write_bytes(bytes(data) + tlog_bytes([("heartbeat", 5.0, {})])[:12])   # cut final frame
    f = read_flight(p)
    sk = f.diagnostics.skipped
    assert sk.get("frame cut by the end of the file") == 1
    assert sum(v for k, v in sk.items() if "garbage" in k or "CRC" in k or "undecodable" in k) >= 1
    assert f.has("roll", "vx")


def test_attitude_quaternion_and_highres_imu(tmp_path):
    """An FRD->NED quaternion for roll 0.1, pitch 0.2 (nose up), heading north comes out as the
    FLU->ENU quaternion of roll 0.1, pitch -0.2, yaw +90 deg; HIGHRES_IMU is SI already."""
    from droneid.core.frames import euler_to_quat, quat_to_euler
    q_ned = euler_to_quat(0.1, 0.2, 0.0)        # the same Z-Y-X formula, applied in NED/FRD
    msgs = []
    for i in range(5):
        msgs.append(("attitude_quaternion", 0.1 * i, dict(time_boot_ms=i, q1=q_ned[0], q2=q_ned[1], q3=q_ned[2],
                                                         q4=q_ned[3], rollspeed=0, pitchspeed=0, yawspeed=0)))
        msgs.append(("highres_imu", 0.1 * i + 0.01, dict(time_usec=i, xacc=0.5, yacc=0.25, zacc=-9.8, xgyro=0.1,
                                                          ygyro=0.2, zgyro=0.3, xmag=0, ymag=0, zmag=0,
                                                          abs_pressure=0, diff_pressure=0, pressure_alt=0,
                                                          temperature=0, fields_updated=0)))
    p = tmp_path / "q.tlog"
    p.write_bytes(tlog_bytes(msgs))
    f = read_flight(p)
    q = np.column_stack([f[n].values for n in ("qw", "qx", "qy", "qz")])
    r, pch, y = quat_to_euler(q)
    assert np.allclose(r, 0.1) and np.allclose(pch, -0.2) and np.allclose(y, math.pi / 2)
    assert np.allclose(f["az"].values, 9.8) and np.allclose(f["ay"].values, -0.25)
    assert np.allclose(f["wx"].values, 0.1) and np.allclose(f["wz"].values, -0.3)
