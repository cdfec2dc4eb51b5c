"""Write a :class:`Flight` as a ROS 2 MCAP file (CDR encoding, ros2msg schemas), with
``mcap_ros2.writer``.

ROS uses ENU world / FLU body (REP-103) like droneid, so no frame conversion happens.

==========================  ============================  ===================================================
topic                       type                          content
==========================  ============================  ===================================================
``/drone/pose``             geometry_msgs/msg/PoseStamped  x y z, attitude quaternion (frame_id ``map``)
``/drone/twist``            geometry_msgs/msg/TwistStamped linear = vx vy vz (world ENU, frame_id ``map``),
                                                          angular = body rates wx wy wz (FLU, as in Imu)
``/drone/imu``              sensor_msgs/msg/Imu           orientation, angular_velocity = wx wy wz,
                                                          linear_acceleration = ax ay az (frame ``base_link``)
``/drone/battery``          sensor_msgs/msg/BatteryState  voltage (current NaN when unknown)
``/drone/throttle``         std_msgs/msg/Float32          throttle 0..1
``/drone/thrust``           std_msgs/msg/Float32          collective thrust (N)
``/drone/motors``           std_msgs/msg/Float32MultiArray motor1..motorN (0..1), dim label ``motors``
``/drone/rpm1`` .. ``16``   std_msgs/msg/Float32          motor speeds rpm1..rpmN (rpm)
==========================  ============================  ===================================================

Log and header times are ``EPOCH (2024-01-01 UTC) + t`` in ns, never the wall clock (readers
that count from the earliest stamp shift a flight that does not start at 0). Euler angles or
quaternion missing from the flight are derived from the other; a pose without any attitude gets
a NaN orientation (not available), never a made-up identity.
Precision: float64 except Float32 topics, battery voltage (float32).
"""
from __future__ import annotations

import io
import os

import numpy as np

from droneid.core.io_util import atomic_write_bytes

from ._writer_util import EPOCH_NS, complete_attitude, group, require_some

__all__ = ["write_mcap", "SCHEMAS", "TOPICS"]

_SEP = "\n" + "=" * 80 + "\n"

_HEADER = """MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id"""
_TIME = """MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec"""
_VECTOR3 = """MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z"""
_QUATERNION = """MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1"""
_POINT = """MSG: geometry_msgs/Point
float64 x
float64 y
float64 z"""
_POSE = """MSG: geometry_msgs/Pose
Point position
Quaternion orientation"""
_TWIST = """MSG: geometry_msgs/Twist
Vector3 linear
Vector3 angular"""
_LAYOUT = """MSG: std_msgs/MultiArrayLayout
MultiArrayDimension[] dim
uint32 data_offset"""
_DIM = """MSG: std_msgs/MultiArrayDimension
string label
uint32 size
uint32 stride"""


def _schema(main: str, *deps: str) -> str:
    return _SEP.join((main,) + deps) + "\n"


#: ROS 2 message definitions (ros2msg text, dependencies appended as rosbag2 does)
SCHEMAS = {
    "geometry_msgs/msg/PoseStamped": _schema(
        "std_msgs/Header header\nPose pose", _POSE, _POINT, _QUATERNION, _HEADER, _TIME),
    "geometry_msgs/msg/TwistStamped": _schema(
        "std_msgs/Header header\nTwist twist", _TWIST, _VECTOR3, _HEADER, _TIME),
    "sensor_msgs/msg/Imu": _schema(
        "std_msgs/Header header\n"
        "geometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance",
        _HEADER, _TIME, _QUATERNION, _VECTOR3),
    "sensor_msgs/msg/BatteryState": _schema(
        "uint8 POWER_SUPPLY_STATUS_UNKNOWN = 0\n"
        "uint8 POWER_SUPPLY_STATUS_DISCHARGING = 2\n"
        "uint8 POWER_SUPPLY_HEALTH_UNKNOWN = 0\n"
        "uint8 POWER_SUPPLY_TECHNOLOGY_LIPO = 3\n"
        "std_msgs/Header header\n"
        "float32 voltage\nfloat32 temperature\nfloat32 current\nfloat32 charge\nfloat32 capacity\n"
        "float32 design_capacity\nfloat32 percentage\nuint8 power_supply_status\n"
        "uint8 power_supply_health\nuint8 power_supply_technology\nbool present\n"
        "float32[] cell_voltage\nfloat32[] cell_temperature\nstring location\nstring serial_number",
        _HEADER, _TIME),
    "std_msgs/msg/Float32": _schema("float32 data"),
    "std_msgs/msg/Float32MultiArray": _schema(
        "MultiArrayLayout layout\nfloat32[] data", _LAYOUT, _DIM),
}

TOPICS = {
    "/drone/pose": "geometry_msgs/msg/PoseStamped",
    "/drone/twist": "geometry_msgs/msg/TwistStamped",
    "/drone/imu": "sensor_msgs/msg/Imu",
    "/drone/battery": "sensor_msgs/msg/BatteryState",
    "/drone/throttle": "std_msgs/msg/Float32",
    "/drone/thrust": "std_msgs/msg/Float32",
    "/drone/motors": "std_msgs/msg/Float32MultiArray",
    **{f"/drone/rpm{i}": "std_msgs/msg/Float32" for i in range(1, 17)},
}

_COV_UNKNOWN = [0.0] * 9         # REP-145: all zero = covariance unknown
_UNKNOWN_COV = [-1.0] + [0.0] * 8   # REP-145: first element -1 = this quantity is not provided


def write_mcap(flight, path) -> str:
    """Write ``flight`` to ``path`` as a ROS 2 ``.mcap`` (atomically); returns the path."""
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer

    path = os.fspath(path)
    require_some(flight, path, "mcap")
    flight = complete_attitude(flight)
    msgs: list[tuple[int, int, str, dict]] = []   # (t_ns, order, topic, message)

    def stamp(t_s):
        ns = EPOCH_NS + int(round(t_s * 1e9))
        return ns, {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}

    def header(t_s, frame):
        ns, st = stamp(t_s)
        return ns, {"stamp": st, "frame_id": frame}

    quat = ("qw", "qx", "qy", "qz")
    g = group(flight, ("x", "y", "z") + quat, required=("x", "y", "z"))
    if g:
        t, v = g
        q = _quat_or_nan(v)
        for i in range(t.size):
            ns, h = header(t[i], "map")
            msgs.append((ns, 0, "/drone/pose", {
                "header": h,
                "pose": {"position": {"x": float(v["x"][i]), "y": float(v["y"][i]), "z": float(v["z"][i])},
                         "orientation": q[i]}}))
    g = group(flight, ("vx", "vy", "vz", "wx", "wy", "wz"), required=("vx", "vy", "vz"))
    if g:
        t, v = g
        for i in range(t.size):
            ns, h = header(t[i], "map")
            msgs.append((ns, 1, "/drone/twist", {"header": h, "twist": {
                "linear": _vec(v, ("vx", "vy", "vz"), i), "angular": _vec(v, ("wx", "wy", "wz"), i)}}))
    imu = ("ax", "ay", "az", "wx", "wy", "wz")
    if any(flight.has(n) for n in imu):
        first = next(n for n in imu if flight.has(n))
        t, v = group(flight, (first,) + imu + quat, required=(first,))
        q = _quat_or_nan(v)
        has_q = all(flight.has(n) for n in quat)
        for i in range(t.size):
            ns, h = header(t[i], "base_link")
            msgs.append((ns, 2, "/drone/imu", {
                "header": h, "orientation": q[i],
                "orientation_covariance": _COV_UNKNOWN if has_q else _UNKNOWN_COV,
                "angular_velocity": _vec(v, ("wx", "wy", "wz"), i),
                "angular_velocity_covariance": _COV_UNKNOWN if flight.has("wx") else _UNKNOWN_COV,
                "linear_acceleration": _vec(v, ("ax", "ay", "az"), i),
                "linear_acceleration_covariance": _COV_UNKNOWN if flight.has("ax") else _UNKNOWN_COV}))
    g = group(flight, ("battery_voltage", "battery_current"), required=("battery_voltage",))
    if g:
        t, v = g
        nan = float("nan")
        for i in range(t.size):
            ns, h = header(t[i], "")
            msgs.append((ns, 3, "/drone/battery", {
                "header": h, "voltage": float(v["battery_voltage"][i]), "temperature": nan,
                "current": float(v["battery_current"][i]), "charge": nan, "capacity": nan,
                "design_capacity": nan, "percentage": nan, "power_supply_status": 2,
                "power_supply_health": 0, "power_supply_technology": 3, "present": True,
                "cell_voltage": [], "cell_temperature": [], "location": "", "serial_number": ""}))
    for order, (name, topic) in enumerate((("throttle", "/drone/throttle"), ("thrust", "/drone/thrust")), 4):
        if flight.has(name):
            s = flight[name]
            for ti, vi in zip(s.t, s.values):
                msgs.append((stamp(ti)[0], order, topic, {"data": float(vi)}))
    for i in range(1, 17):
        if flight.has(f"rpm{i}"):
            s = flight[f"rpm{i}"]
            for ti, vi in zip(s.t, s.values):
                msgs.append((stamp(ti)[0], 7, f"/drone/rpm{i}", {"data": float(vi)}))
    motors = [f"motor{i}" for i in range(1, 17) if flight.has(f"motor{i}")]
    if motors:
        n_out = max(int(m[5:]) for m in motors)
        names = tuple(f"motor{i}" for i in range(1, n_out + 1))
        t, v = group(flight, names, required=(motors[0],))
        for i in range(t.size):
            msgs.append((stamp(t[i])[0], 6, "/drone/motors", {
                "layout": {"dim": [{"label": "motors", "size": n_out, "stride": n_out}], "data_offset": 0},
                "data": [float(v[nm][i]) for nm in names]}))

    msgs.sort(key=lambda m: (m[0], m[1]))
    buf = io.BytesIO()
    writer = Writer(buf, compression=CompressionType.ZSTD)
    schemas = {}
    seq: dict[str, int] = {}
    for ns, _, topic, msg in msgs:
        dtype = TOPICS[topic]
        if dtype not in schemas:
            schemas[dtype] = writer.register_msgdef(dtype, SCHEMAS[dtype])
        seq[topic] = seq.get(topic, -1) + 1
        writer.write_message(topic, schemas[dtype], msg, log_time=ns, publish_time=ns, sequence=seq[topic])
    writer.finish()
    atomic_write_bytes(path, buf.getvalue())
    return path


def _vec(v, names, i):
    return {ax: float(np.nan_to_num(v[n][i])) for ax, n in zip("xyz", names)}


def _quat_or_nan(v):
    q = np.column_stack([v["qw"], v["qx"], v["qy"], v["qz"]])
    return [{"x": float(b), "y": float(c), "z": float(d), "w": float(a)} for a, b, c, d in q]
