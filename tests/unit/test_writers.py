"""Round trips: a simulated flight written as .tlog, .mcap and Motive CSV reads back to the same
signals within each format's precision.

The readers here are deliberately minimal and independent of droneid's parsers (pymavlink's own
mavutil, mcap_ros2's own reader, pandas); ``test_read_flight_round_trip`` also runs the project
readers (``parsers.read_flight``) when they are present. The Motive header against a real
Motive export: tests/real_logs/test_writers_real.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from droneid.errors import DataError
from droneid.logs.flight import Flight, Signal
from droneid.core.frames import (euler_frd_ned_to_flu_enu, euler_to_quat, ned_to_enu,
                            quat_flu_enu_from_frd_ned, wrap_angle)
from droneid.simulation.simulator import simulate
from parsers.mcap_writer import write_mcap
from parsers.motive_writer import motive_to_enu, write_motive_csv
from parsers.tlog_writer import write_tlog


@pytest.fixture(scope="module")
def flight():
    return simulate(path="eight", duration_s=6.0, rate_hz=20.0, seed=5,
                    effects={"battery_sag": None}).flight


def _close(got_t, got, flight, name, atol, angle=False):
    s = flight[name]
    np.testing.assert_allclose(got_t, s.t, atol=1e-6, err_msg=name)
    d = np.asarray(got) - s.values
    if angle:
        d = wrap_angle(d)
    assert np.max(np.abs(d)) <= atol, f"{name}: max error {np.max(np.abs(d))} > {atol}"


# ---------------------------------------------------------------------------------------------
def test_frame_helpers_are_involutions():
    """The writers use frames' NED->ENU helpers backwards: they are their own inverses."""
    rng = np.random.default_rng(0)
    v = rng.normal(size=(3, 50))
    np.testing.assert_allclose(ned_to_enu(*ned_to_enu(*v)), v)
    ang = rng.uniform(-1, 1, size=(3, 50))
    back = euler_frd_ned_to_flu_enu(*euler_frd_ned_to_flu_enu(*ang))
    np.testing.assert_allclose(np.array(back), ang, atol=1e-12)
    q = euler_to_quat(*ang)
    q = np.where(q[:, :1] < 0, -q, q)
    np.testing.assert_allclose(quat_flu_enu_from_frd_ned(quat_flu_enu_from_frd_ned(q)), q, atol=1e-12)


def _read_tlog_minimal(path):
    from pymavlink import mavutil
    conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    out: dict[str, list] = {}
    t0 = None
    while True:
        m = conn.recv_match()
        if m is None:
            break
        if t0 is None:
            t0 = m._timestamp
        out.setdefault(m.get_type(), []).append((round(m._timestamp - t0, 6), m))
    conn.close()
    return out


def test_tlog_round_trip(flight, tmp_path):
    path = write_tlog(flight, tmp_path / "f.tlog")
    msgs = _read_tlog_minimal(path)
    assert {"HEARTBEAT", "ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "HIGHRES_IMU",
            "SERVO_OUTPUT_RAW", "VFR_HUD", "SYS_STATUS"} <= set(msgs)

    def col(name, attr):
        rows = msgs[name]
        return np.array([t for t, _ in rows]), np.array([getattr(m, attr) for _, m in rows], float)

    hb = [m for _, m in msgs["HEARTBEAT"]]
    assert all(m.type == 2 and m.base_mode & 128 for m in hb) and len(hb) == 7
    t, r = col("ATTITUDE", "roll")
    _, p = col("ATTITUDE", "pitch")
    _, y = col("ATTITUDE", "yaw")
    r, p, y = euler_frd_ned_to_flu_enu(r, p, y)
    for name, val in (("roll", r), ("pitch", p), ("yaw", y)):
        _close(t, val, flight, name, 1e-6, angle=True)
    _, q = col("ATTITUDE", "pitchspeed")
    _close(t, -q, flight, "wy", 1e-6)
    t, q1 = col("ATTITUDE_QUATERNION", "q1")
    q = np.column_stack([q1] + [col("ATTITUDE_QUATERNION", a)[1] for a in ("q2", "q3", "q4")])
    q = quat_flu_enu_from_frd_ned(q)
    for k, name in enumerate(("qw", "qx", "qy", "qz")):
        _close(t, q[:, k], flight, name, 1e-6)
    t, n = col("LOCAL_POSITION_NED", "x")
    e, d = col("LOCAL_POSITION_NED", "y")[1], col("LOCAL_POSITION_NED", "z")[1]
    vn, ve, vd = (col("LOCAL_POSITION_NED", a)[1] for a in ("vx", "vy", "vz"))
    for name, val in zip(("x", "y", "z", "vx", "vy", "vz"), ned_to_enu(n, e, d) + ned_to_enu(vn, ve, vd)):
        _close(t, val, flight, name, 1e-5)
    t, za = col("HIGHRES_IMU", "zacc")
    _close(t, -za, flight, "az", 1e-5)
    _close(t, -col("HIGHRES_IMU", "yacc")[1], flight, "ay", 1e-5)
    _close(t, -col("HIGHRES_IMU", "zgyro")[1], flight, "wz", 1e-6)
    t, s1 = col("SERVO_OUTPUT_RAW", "servo1_raw")
    _close(t, (s1 - 1000) / 1000, flight, "motor1", 5e-4 + 1e-9)
    _close(t, (col("SERVO_OUTPUT_RAW", "servo4_raw")[1] - 1000) / 1000, flight, "motor4", 5e-4 + 1e-9)
    t, thr = col("VFR_HUD", "throttle")
    _close(t, thr / 100, flight, "throttle", 5e-3 + 1e-9)
    t, mv = col("SYS_STATUS", "voltage_battery")
    _close(t, mv / 1000, flight, "battery_voltage", 5e-4 + 1e-9)


def test_mcap_round_trip(flight, tmp_path):
    from types import SimpleNamespace

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    path = write_mcap(flight, tmp_path / "f.mcap")
    by: dict[str, list] = {}
    with open(path, "rb") as fh:
        for _, channel, message, ros_msg in make_reader(fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            by.setdefault(channel.topic, []).append(SimpleNamespace(ros_msg=ros_msg, log_time_ns=message.log_time))
    t0 = 1_704_067_200 * 10**9

    def times(topic, from_header=True):
        if from_header:
            return np.array([(m.ros_msg.header.stamp.sec * 10**9 + m.ros_msg.header.stamp.nanosec - t0) * 1e-9
                             for m in by[topic]])
        return np.array([(m.log_time_ns - t0) * 1e-9 for m in by[topic]])

    t = times("/drone/pose")
    pos = [m.ros_msg.pose.position for m in by["/drone/pose"]]
    ori = [m.ros_msg.pose.orientation for m in by["/drone/pose"]]
    for name, val in (("x", [p.x for p in pos]), ("y", [p.y for p in pos]), ("z", [p.z for p in pos]),
                      ("qw", [o.w for o in ori]), ("qx", [o.x for o in ori]), ("qz", [o.z for o in ori])):
        _close(t, val, flight, name, 1e-12)
    t = times("/drone/twist")
    tw = [m.ros_msg.twist for m in by["/drone/twist"]]
    _close(t, [w.linear.x for w in tw], flight, "vx", 1e-12)
    _close(t, [w.angular.z for w in tw], flight, "wz", 1e-12)
    t = times("/drone/imu")
    imu = [m.ros_msg for m in by["/drone/imu"]]
    _close(t, [i.linear_acceleration.z for i in imu], flight, "az", 1e-12)
    _close(t, [i.angular_velocity.y for i in imu], flight, "wy", 1e-12)
    t = times("/drone/battery")
    _close(t, [m.ros_msg.voltage for m in by["/drone/battery"]], flight, "battery_voltage", 1e-5)
    t = times("/drone/throttle", from_header=False)
    _close(t, [m.ros_msg.data for m in by["/drone/throttle"]], flight, "throttle", 1e-7)
    _close(times("/drone/thrust", False), [m.ros_msg.data for m in by["/drone/thrust"]], flight, "thrust", 1e-6)
    mot = np.array([m.ros_msg.data for m in by["/drone/motors"]])
    _close(times("/drone/motors", False), mot[:, 2], flight, "motor3", 1e-7)
    assert by["/drone/motors"][0].ros_msg.layout.dim[0].label == "motors"


def _read_motive_minimal(path):
    import pandas as pd
    with open(path, newline="") as fh:
        text = fh.read()
    lines = text.split("\r\n")
    meta = lines[0].split(",")
    meta = dict(zip(meta[0::2], meta[1::2]))
    hdr = next(i for i, ln in enumerate(lines) if ln.startswith("Frame,"))
    kinds = lines[hdr - 1].split(",")
    df = pd.read_csv(path, skiprows=hdr + 1, header=None)
    return meta, lines, kinds, df


def test_motive_round_trip(flight, tmp_path):
    path = write_motive_csv(flight, tmp_path / "f.csv", body="bebop")
    meta, lines, kinds, df = _read_motive_minimal(path)
    assert meta["Format Version"] == "1.23" and meta["Rotation Type"] == "Quaternion"
    assert float(meta["Capture Frame Rate"]) == pytest.approx(20.0)
    assert lines[1] == "" and lines[2].startswith(",Type,Rigid Body") and lines[3] == ",Name," + ",".join(["bebop"] * 8)
    assert kinds[2:6] == ["Rotation"] * 4 and kinds[6:9] == ["Position"] * 3
    t = df[1].to_numpy()
    (x, y, z), (qw, qx, qy, qz) = motive_to_enu(*(df[k].to_numpy() for k in (6, 7, 8, 2, 3, 4, 5)))
    for name, val in (("x", x), ("y", y), ("z", z)):
        _close(t, val, flight, name, 5e-7 + 1e-12)
    q = np.column_stack([qw, qx, qy, qz])
    ref = np.column_stack([flight[n].values for n in ("qw", "qx", "qy", "qz")])
    q *= np.sign(np.sum(q * ref, axis=1))[:, None]
    np.testing.assert_allclose(q, ref, atol=5e-7 + 1e-12)
    np.testing.assert_array_equal(df[0].to_numpy(), np.arange(len(flight["x"])))


def test_motive_axes_are_y_up_and_right_handed(tmp_path):
    """A drone pitched nose down while facing east: Motive Y is up, the rotation is about -Z."""
    t = np.array([0.0, 0.01])
    q = euler_to_quat(np.zeros(2), np.full(2, 0.2), np.zeros(2))
    sig = {"x": [1.0, 1.0], "y": [2.0, 2.0], "z": [3.0, 3.0],
           "qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3]}
    f = Flight({k: Signal(k, t, np.asarray(v), "m") for k, v in sig.items()})
    path = write_motive_csv(f, tmp_path / "a.csv")
    _, _, _, df = _read_motive_minimal(path)
    assert tuple(df.iloc[0, 6:9]) == (1.0, 3.0, -2.0)
    # nose down about FLU +y (north axis) = about Motive -Z; rotate body x (east = Motive X)
    from droneid.core.frames import quat_to_matrix
    qX, qY, qZ, qW = df.iloc[0, 2:6]
    R = quat_to_matrix(np.array([qW, qX, qY, qZ]))
    fwd = R @ np.array([1.0, 0.0, 0.0])
    assert fwd[1] < -0.15      # nose points down in Motive (Y up)
    assert abs(fwd[2]) < 1e-6


def test_writers_are_deterministic(flight, tmp_path):
    for write, ext in ((write_tlog, "tlog"), (write_mcap, "mcap"), (write_motive_csv, "csv")):
        a = write(flight, tmp_path / "a" / f"f.{ext}")
        b = write(flight, tmp_path / "b" / f"f.{ext}")
        assert open(a, "rb").read() == open(b, "rb").read(), ext


def test_writers_need_signals(tmp_path):
    t = np.array([0.0, 0.1])
    f = Flight({"x": Signal("x", t, np.zeros(2), "m")})
    with pytest.raises(DataError, match="lacks"):
        write_motive_csv(f, tmp_path / "a.csv")
    with pytest.raises(DataError):
        write_tlog(Flight({}), tmp_path / "a.tlog")
    assert not (tmp_path / "a.csv").exists()


def test_read_flight_round_trip(flight, tmp_path):
    """The project readers read what the writers wrote, within format precision."""
    import parsers
    files = {"tlog": write_tlog(flight, tmp_path / "f.tlog"), "mcap": write_mcap(flight, tmp_path / "f.mcap"),
             "motive_csv": write_motive_csv(flight, tmp_path / "f.csv")}
    tol = {"x": 1e-6, "y": 1e-6, "z": 1e-6, "roll": 1e-6, "pitch": 1e-6, "yaw": 1e-6, "vx": 1e-6,
           "vy": 1e-6, "vz": 1e-6, "qw": 1e-6, "qx": 1e-6, "qy": 1e-6, "qz": 1e-6, "wx": 1e-6,
           "wy": 1e-6, "wz": 1e-6, "ax": 1e-5, "ay": 1e-5, "az": 1e-5, "throttle": 5e-3 + 1e-9,
           "motor1": 5e-4 + 1e-9, "motor2": 5e-4 + 1e-9, "motor3": 5e-4 + 1e-9, "motor4": 5e-4 + 1e-9,
           "battery_voltage": 5e-4 + 1e-9, "thrust": 1e-5}
    pose = ("x", "y", "z", "roll", "pitch", "yaw", "qw", "qx", "qy", "qz")
    carried = {
        "tlog": tuple(n for n in tol if n != "thrust"),  # no MAVLink field for thrust (N)
        "mcap": pose + ("vx", "vy", "vz", "wx", "wy", "wz", "ax", "ay", "az", "battery_voltage",
                        "throttle", "thrust", "motor1", "motor2", "motor3", "motor4"),
        "motive_csv": pose,                       # pose only; 6 decimals
    }
    for fmt, path in files.items():
        assert parsers.detect_format(path) == fmt
        got = parsers.read_flight(path)
        for n in carried[fmt]:
            assert got.has(n), (fmt, n, got.names)
            s, ref = got[n], flight[n]
            np.testing.assert_allclose(s.t, ref.t, atol=1e-6, err_msg=f"{fmt} {n} time")
            d = s.values - ref.values
            if n in ("roll", "pitch", "yaw"):
                d = wrap_angle(d)
            atol = 2e-6 if fmt == "motive_csv" else tol[n]
            assert np.max(np.abs(d)) <= atol, (fmt, n, np.max(np.abs(d)))
    tl = parsers.read_flight(files["tlog"])
    assert tl.segments["armed"] == flight.segments["armed"]
    assert tl.segments["in_flight"] == flight.segments["in_flight"]


def test_writers_fill_attitude_and_keep_time_origin(tmp_path):
    """A flight with Euler angles only, starting at t = 0.5 s: the tlog still carries the quaternion
    and its times; the MCAP pose gets the quaternion from the angles (not an identity)."""
    t = np.arange(10) * 0.1 + 0.5
    roll, pitch, yaw = 0.1 * np.sin(t), 0.05 * np.cos(t), wrap_angle(3.0 + 0.2 * t)
    sig = {"x": t, "y": -t, "z": 1 + 0 * t, "roll": roll, "pitch": pitch, "yaw": yaw}
    f = Flight({k: Signal(k, t, np.asarray(v), "1") for k, v in sig.items()})
    msgs = _read_tlog_minimal(write_tlog(f, tmp_path / "e.tlog"))
    assert msgs["HEARTBEAT"][0][0] == 0.0
    tq = np.array([tt for tt, _ in msgs["ATTITUDE_QUATERNION"]])
    np.testing.assert_allclose(tq, t, atol=1e-6)
    q = quat_flu_enu_from_frd_ned(np.array([[m.q1, m.q2, m.q3, m.q4] for _, m in msgs["ATTITUDE_QUATERNION"]]))
    qref = euler_to_quat(roll, pitch, yaw)
    np.testing.assert_allclose(q, np.where(qref[:, :1] < 0, -qref, qref), atol=1e-6)
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(write_mcap(f, tmp_path / "e.mcap"), "rb") as fh:
        oris = [m.pose.orientation for _, _, _, m in
                make_reader(fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=["/drone/pose"])]
    assert abs(oris[0].w) < 0.2 and abs(oris[0].z) > 0.98      # yaw ~ 3.1 rad, not identity
