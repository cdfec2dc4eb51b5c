"""MCAP reader on files written here with mcap-ros2's writer (and a JSON channel): every role,
topic selection and overrides, NED frame_ids, the fast CDR path equal to the generic decoder."""
from __future__ import annotations

import json

import numpy as np
import pytest

from droneid.errors import ConfigError, LogFormatError
from droneid.core.frames import euler_to_quat
from parsers import detect_format, read_flight
from parsers.mcap_log import read_mcap

HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" \
         "================================================================================\n" \
         "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
SEP = "================================================================================\n"
POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
QUAT = "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
VEC3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
POSE = "MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n"
TWIST = "MSG: geometry_msgs/Twist\nVector3 linear\nVector3 angular\n"
DEFS = {
    "geometry_msgs/msg/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose\n" + SEP + HEADER
    + SEP + POSE + SEP + POINT + SEP + QUAT,
    "geometry_msgs/msg/TwistStamped": "std_msgs/Header header\ngeometry_msgs/Twist twist\n" + SEP + HEADER
    + SEP + TWIST + SEP + VEC3,
    "sensor_msgs/msg/Imu": "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
    "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
    "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
    "float64[9] linear_acceleration_covariance\n" + SEP + HEADER + SEP + QUAT + SEP + VEC3,
    "nav_msgs/msg/Odometry": "std_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n" + SEP + HEADER
    + SEP + "MSG: geometry_msgs/PoseWithCovariance\nPose pose\nfloat64[36] covariance\n" + SEP + POSE
    + SEP + POINT + SEP + QUAT + SEP
    + "MSG: geometry_msgs/TwistWithCovariance\nTwist twist\nfloat64[36] covariance\n" + SEP + TWIST
    + SEP + VEC3,
    "sensor_msgs/msg/BatteryState": "std_msgs/Header header\nfloat32 voltage\nfloat32 temperature\n"
    "float32 current\n" + SEP + HEADER,
}
T0 = 1_700_000_000


def _hdr(t, frame):
    sec = int(t)
    return {"stamp": {"sec": T0 + sec, "nanosec": int(round((t - sec) * 1e9))}, "frame_id": frame}


def _write(path, n=200, frame="map", body_frame="base_link", extra_pose_topic=False, json_twist=False):
    from mcap_ros2.writer import Writer
    t = np.arange(n) * 0.01
    yaw = 0.5 * t
    q = euler_to_quat(0.1 + 0 * t, 0.2 + 0 * t, yaw)                 # (w, x, y, z)
    with open(path, "wb") as f:
        w = Writer(f)
        sch = {k: w.register_msgdef(k, v) for k, v in DEFS.items()}
        for i, ti in enumerate(t):
            ns = int((T0 + ti) * 1e9) + 5_000_000                      # log time 5 ms after stamp
            pose = {"position": {"x": 1.0 * ti, "y": 2.0, "z": 3.0 + ti},
                    "orientation": {"x": q[i, 1], "y": q[i, 2], "z": q[i, 3], "w": q[i, 0]}}
            w.write_message("/drone/pose", sch["geometry_msgs/msg/PoseStamped"],
                            {"header": _hdr(ti, frame), "pose": pose}, log_time=ns, publish_time=ns)
            if extra_pose_topic and i % 2 == 0:
                w.write_message("/other/pose", sch["geometry_msgs/msg/PoseStamped"],
                                {"header": _hdr(ti, frame), "pose": pose}, log_time=ns, publish_time=ns)
            w.write_message("/drone/imu", sch["sensor_msgs/msg/Imu"],
                            {"header": _hdr(ti, body_frame), "orientation": pose["orientation"],
                             "orientation_covariance": [0.0] * 9,
                             "angular_velocity": {"x": 0.1, "y": 0.2, "z": 0.3},
                             "angular_velocity_covariance": [0.0] * 9,
                             "linear_acceleration": {"x": 0.5, "y": -0.5, "z": 9.81},
                             "linear_acceleration_covariance": [0.0] * 9}, log_time=ns, publish_time=ns)
            w.write_message("/drone/odom", sch["nav_msgs/msg/Odometry"],
                            {"header": _hdr(ti, frame), "child_frame_id": body_frame,
                             "pose": {"pose": pose, "covariance": [0.0] * 36},
                             "twist": {"twist": {"linear": {"x": 1.0, "y": 0.0, "z": 0.0},
                                                 "angular": {"x": 0.0, "y": 0.0, "z": 0.5}},
                                       "covariance": [0.0] * 36}}, log_time=ns, publish_time=ns)
            if not json_twist:
                w.write_message("/drone/twist", sch["geometry_msgs/msg/TwistStamped"],
                                {"header": _hdr(ti, frame), "twist": {"linear": {"x": 1.0, "y": 0.0, "z": 1.0},
                                                                      "angular": {"x": 0, "y": 0, "z": 0}}},
                                log_time=ns, publish_time=ns)
            if i % 10 == 0:
                w.write_message("/battery", sch["sensor_msgs/msg/BatteryState"],
                                {"header": _hdr(ti, ""), "voltage": 15.5, "temperature": 20.0, "current": -7.5},
                                log_time=ns, publish_time=ns)
        if json_twist:
            mw = w._writer
            sid = mw.register_schema("geometry_msgs/msg/TwistStamped", "jsonschema", b"{}")
            cid = mw.register_channel("/drone/twist", "json", sid)
            for ti in t:
                ns = int((T0 + ti) * 1e9)
                msg = {"header": _hdr(ti, frame), "twist": {"linear": {"x": 1.0, "y": 0.0, "z": 1.0},
                                                            "angular": {"x": 0, "y": 0, "z": 0}}}
                mw.add_message(cid, log_time=ns, data=json.dumps(msg).encode(), publish_time=ns)
        w.finish()
    return t, q


def test_every_role_read_and_fast_path_equals_decoder(tmp_path):
    p = tmp_path / "all.mcap"
    t, q = _write(p)
    assert detect_format(p) == "mcap"
    f = read_flight(p)
    assert f["x"].source.startswith("/drone/pose")               # pose preferred over odom's pose
    assert np.allclose(f["x"].t, t, atol=1e-9)                    # header stamps, not log time
    assert np.allclose(f["pitch"].values, 0.2) and np.allclose(f["roll"].values, 0.1)
    assert np.allclose(f["vx"].values, 1.0) and np.allclose(f["vz"].values, 1.0)   # TwistStamped
    assert np.allclose(f["az"].values, 9.81) and np.allclose(f["wy"].values, 0.2)
    assert np.allclose(f["battery_voltage"].values, 15.5) and np.allclose(f["battery_current"].values, 7.5)
    g = read_mcap(p, _fast=False)
    for n in f.names:
        assert np.array_equal(f[n].values, g[n].values) and np.array_equal(f[n].t, g[n].t), n


def test_odometry_twist_is_rotated_from_body_to_world(tmp_path):
    p = tmp_path / "odom.mcap"
    t, q = _write(p)
    from droneid.core.frames import quat_to_matrix
    v_world = quat_to_matrix(q)[:, :, 0]          # body +x (forward) at 1 m/s, seen in the world
    h = read_flight(_only(tmp_path, p, "/drone/odom"))
    assert h["vx"].source.startswith("/drone/odom")
    assert np.allclose(h["vx"].values, v_world[:, 0]) and np.allclose(h["vy"].values, v_world[:, 1])
    assert np.allclose(h["vz"].values, v_world[:, 2])
    assert np.allclose(h["wz"].values, 0.5)
    assert np.allclose(h["pitch"].values, 0.2)


def _only(tmp_path, src, topic):
    """A copy of ``src`` holding only ``topic`` (plain mcap reader/writer)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer
    out = tmp_path / "only.mcap"
    with open(src, "rb") as fi, open(out, "wb") as fo:
        r = make_reader(fi)
        w = Writer(fo)
        w.start()
        ids = {}
        for schema, ch, msg in r.iter_messages(topics=[topic]):
            if ch.id not in ids:
                sid = w.register_schema(schema.name, schema.encoding, schema.data)
                ids[ch.id] = w.register_channel(ch.topic, ch.message_encoding, sid)
            w.add_message(ids[ch.id], log_time=msg.log_time, data=msg.data, publish_time=msg.publish_time)
        w.finish()
    return out


def test_ned_frame_id_is_converted(tmp_path):
    p = tmp_path / "ned.mcap"
    _write(p, frame="odom_ned", body_frame="base_link_frd")
    f = read_flight(p)
    assert np.allclose(f["y"].values, 1.0 * f["x"].t)            # north (NED x) -> ENU y
    assert np.allclose(f["x"].values, 2.0) and np.allclose(f["z"].values[0], -3.0)
    assert np.allclose(f["vz"].values, -1.0)                      # NED down 1 m/s -> up -1
    assert np.allclose(f["az"].values, -9.81)                     # FRD +z -> FLU -z
    assert any("NED/FRD, converted" in n for n in f.provenance.notes)


def test_json_channel_and_topic_choice(tmp_path):
    p = tmp_path / "json.mcap"
    _write(p, extra_pose_topic=True, json_twist=True)
    f = read_flight(p)
    assert np.allclose(f["vz"].values, 1.0) and f["vx"].source == "/drone/twist twist.linear"
    assert any("several pose topics" in w for w in f.diagnostics.warnings)
    g = read_flight(p, topics={"pose": "/other/pose"})
    assert len(g["x"]) == len(f["x"]) // 2
    with pytest.raises(ConfigError, match="did you mean 'pose'"):
        read_flight(p, topics={"poze": "/drone/pose"})
    with pytest.raises(ConfigError, match="not in"):
        read_flight(p, topics={"pose": "/nope"})


def test_cut_mcap_keeps_what_came_before(tmp_path):
    p = tmp_path / "all.mcap"
    _write(p, n=400)
    data = p.read_bytes()
    q = tmp_path / "cut.mcap"
    q.write_bytes(data[: int(len(data) * 0.6)])
    f = read_flight(q)
    assert f.diagnostics.total_skipped >= 1 and f.diagnostics.warnings
    assert 0 < len(f["x"]) <= 400


def test_mcap_without_known_topics(tmp_path):
    from mcap.writer import Writer
    p = tmp_path / "other.mcap"
    with open(p, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("std_msgs/msg/String", "ros2msg", b"string data")
        cid = w.register_channel("/chatter", "cdr", sid)
        w.add_message(cid, log_time=1, data=b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00", publish_time=1)
        w.finish()
    with pytest.raises(LogFormatError, match="no topic with a known schema.*chatter"):
        read_flight(p)
