"""PX4 ULog ``.ulg`` (pyulog) -> :class:`Flight`.

Only the topics below are loaded (pyulog's ``message_name_filter_list``), instance 0 of each
(multi_id 0). Time: each topic's ``timestamp`` (µs since boot) minus the log's start time stamp.

* vehicle_attitude ``q[0..3]`` (FRD body -> NED world) -> qw..qz via
  :func:`quat_flu_enu_from_frd_ned`, and roll/pitch/yaw from that quaternion
* vehicle_local_position x y z vx vy vz (NED; samples flagged invalid by xy_valid / z_valid /
  v_xy_valid / v_z_valid are skipped and counted) -> ENU
* vehicle_angular_velocity xyz (FRD) -> wx wy wz (FLU); else sensor_combined gyro_rad
* sensor_combined accelerometer_m_s2 (FRD) -> ax ay az (FLU); else vehicle_acceleration xyz
* esc_status esc[i].esc_rpm (i < esc_count, never all 0) -> rpm{i+1} (|rpm|)
* actuator_motors control[i] (0..1; -1..1 for reversible motors -> 0..1) -> motor{i+1}; else
  actuator_outputs output[i] (PWM -> 0..1 with PWM_MAIN_MINn/MAXn, else PWM_MAIN_MIN/MAX, else
  1000-2000; only the first ``noutputs`` channels that ever leave 0)
* vehicle_thrust_setpoint xyz[2] (FRD, negative up) -> throttle = -xyz[2] (0..1)
* battery_status voltage_v, current_a
* vehicle_status arming_state (2 = armed) -> "armed" segments, nav_state -> "mode" events
* vehicle_land_detected landed -> "in_flight" segments
"""
from __future__ import annotations

import logging
import os

import numpy as np

from droneid.errors import LogFormatError
from droneid.logs.flight import Flight, vehicle_from_mav_type

from ._build import FlightBuilder, flu_columns
from ._px4 import (add_arming, add_attitude_quat, add_battery, add_landed, add_local_ned, add_pwm_motors,
                   vehicle_type_from_params)
from ._registry import Reader
from ._guard import BoundedReader, ReaderLoopError

log = logging.getLogger(__name__)

__all__ = ["read_ulog", "TOPICS"]

TOPICS = ("esc_status", "vehicle_attitude", "vehicle_local_position", "vehicle_angular_velocity",
          "sensor_combined", "vehicle_acceleration", "actuator_motors", "actuator_outputs",
          "vehicle_thrust_setpoint", "battery_status", "vehicle_status", "vehicle_land_detected")

#: fields a topic must have to be used (a damaged format definition may lack them)
_NEEDED = {
    "vehicle_attitude": tuple(f"q[{i}]" for i in range(4)),
    "vehicle_local_position": ("x", "y", "z", "vx", "vy", "vz"),
    "vehicle_angular_velocity": ("xyz[0]", "xyz[1]", "xyz[2]"),
    "sensor_combined": tuple(f"gyro_rad[{i}]" for i in range(3))
    + tuple(f"accelerometer_m_s2[{i}]" for i in range(3)),
    "vehicle_acceleration": ("xyz[0]", "xyz[1]", "xyz[2]"),
    "vehicle_thrust_setpoint": ("xyz[2]",),
    "battery_status": ("voltage_v", "current_a"),
    "vehicle_status": ("arming_state", "nav_state"),
    "vehicle_land_detected": ("landed",),
    "esc_status": ("esc[0].esc_rpm",),
}

_NAV_STATES = {0: "MANUAL", 1: "ALTCTL", 2: "POSCTL", 3: "AUTO_MISSION", 4: "AUTO_LOITER",
               5: "AUTO_RTL", 10: "ACRO", 12: "DESCEND", 13: "TERMINATION", 14: "OFFBOARD",
               15: "STAB", 17: "AUTO_TAKEOFF", 18: "AUTO_LAND", 19: "AUTO_FOLLOW_TARGET",
               20: "AUTO_PRECLAND", 21: "ORBIT", 22: "AUTO_VTOL_TAKEOFF"}


def read_ulog(path) -> Flight:
    """Read a PX4 ULog into a :class:`Flight` (see the module doc)."""
    path = os.fspath(path)
    from pyulog import ULog
    size = os.path.getsize(path)
    # pyulog can seek back and re-read the same bytes forever on damage: bound what it may read
    f = BoundedReader(open(path, "rb"), limit_bytes=4 * size + (1 << 20), max_stalled_reads=100_000)
    try:
        ulog = ULog(f, message_name_filter_list=list(TOPICS), disable_str_exceptions=True)
    except ReaderLoopError as exc:
        raise LogFormatError(path, f"damaged ULog: pyulog stopped making progress ({exc})") from None
    except Exception as exc:  # pyulog raises TypeError/IndexError/struct.error on bad files
        raise LogFormatError(path, f"not a readable ULog ({type(exc).__name__}: {exc})") from None
    finally:
        f.close()
    b = FlightBuilder(path, "ulog")
    topics = {}
    for d in ulog.data_list:
        if d.multi_id != 0 or d.name not in TOPICS:
            continue
        missing = [k for k in _NEEDED.get(d.name, ()) + ("timestamp",) if k not in d.data]
        if missing:   # a damaged format definition: the topic's fields are not what PX4 writes
            b.skip(f"{d.name}: topic without field(s) {', '.join(missing)} (damaged format)",
                   len(next(iter(d.data.values()), ())))
            continue
        if len(d.data["timestamp"]):
            topics[d.name] = d.data
    # some topics carry samples stamped just before the header's start time: start at the earliest
    # (within 1 s of it; a zero stamp of an uninitialised message must not move the origin)
    floor = ulog.start_timestamp - 1_000_000
    t0 = min([ulog.start_timestamp] + [int(np.min(ts[ts >= floor])) for ts in
                                       (np.asarray(d["timestamp"]) for d in topics.values())
                                       if np.any(ts >= floor)])
    info = ulog.msg_info_dict
    b.firmware = _firmware(info)
    b.vehicle = _vehicle(info, topics.get("vehicle_status"))
    b.vehicle_type, b.vehicle_declared = _vehicle_type(topics.get("vehicle_status"), ulog.initial_parameters)
    if getattr(ulog, "file_corruption", False):
        b.skip("corrupt ULog sections (pyulog resynchronised)", 1)
        b.warn("the ULog file is corrupt in places; pyulog skipped the damaged data")

    def tt(d):
        return (np.asarray(d["timestamp"], float) - t0) * 1e-6

    if "vehicle_attitude" in topics:
        d = topics["vehicle_attitude"]
        q = np.stack([d[f"q[{i}]"] for i in range(4)], axis=-1).astype(float)
        add_attitude_quat(b, tt(d), q, "vehicle_attitude.q")
    if "vehicle_local_position" in topics:
        d = topics["vehicle_local_position"]
        t = tt(d)
        for names, flag, unit, what in ((("x", "y", "z"), ("xy_valid", "z_valid"), "m", "x/y/z"),
                                        (("vx", "vy", "vz"), ("v_xy_valid", "v_z_valid"), "m/s",
                                         "vx/vy/vz")):
            valid = [d[k].astype(bool) if k in d else np.ones(t.size, bool) for k in flag]
            add_local_ned(b, t, names, [d[k] for k in names], valid, unit, f"vehicle_local_position.{what}",
                          tuple(f"vehicle_local_position samples with {k} false" for k in flag))
    if "vehicle_angular_velocity" in topics:
        d = topics["vehicle_angular_velocity"]
        b.add_many(tt(d), flu_columns(("wx", "wy", "wz"), d["xyz[0]"], d["xyz[1]"], d["xyz[2]"]),
                   dict.fromkeys(("wx", "wy", "wz"), "rad/s"), "vehicle_angular_velocity.xyz")
    elif "sensor_combined" in topics:
        d = topics["sensor_combined"]
        b.add_many(tt(d), flu_columns(("wx", "wy", "wz"), *(d[f"gyro_rad[{i}]"] for i in range(3))),
                   dict.fromkeys(("wx", "wy", "wz"), "rad/s"), "sensor_combined.gyro_rad")
    if "sensor_combined" in topics:
        d = topics["sensor_combined"]
        b.add_many(tt(d), flu_columns(("ax", "ay", "az"), *(d[f"accelerometer_m_s2[{i}]"] for i in range(3))),
                   dict.fromkeys(("ax", "ay", "az"), "m/s^2"), "sensor_combined.accelerometer_m_s2")
    elif "vehicle_acceleration" in topics:
        d = topics["vehicle_acceleration"]
        b.add_many(tt(d), flu_columns(("ax", "ay", "az"), d["xyz[0]"], d["xyz[1]"], d["xyz[2]"]),
                   dict.fromkeys(("ax", "ay", "az"), "m/s^2"), "vehicle_acceleration.xyz")
    _motors(b, topics, tt, ulog.initial_parameters)
    if "vehicle_thrust_setpoint" in topics:
        d = topics["vehicle_thrust_setpoint"]
        b.add("throttle", tt(d), -np.asarray(d["xyz[2]"], float), "1", "-vehicle_thrust_setpoint.xyz[2]")
    if "battery_status" in topics:
        d = topics["battery_status"]
        add_battery(b, tt(d), d["voltage_v"], d["current_a"], "battery_status", "voltage_v", "current_a")
    _status(b, topics, tt)
    return b.build()


def _firmware(info) -> str | None:
    """"PX4 v1.11.2 (8583f1da)" from ver_sw_release (0xMMmmppTT) and the git hash."""
    rel, sw = info.get("ver_sw_release"), info.get("ver_sw")
    parts = [str(info.get("sys_name") or "PX4")]
    if isinstance(rel, (int, np.integer)) and rel > 0:
        parts.append(f"v{(rel >> 24) & 0xFF}.{(rel >> 16) & 0xFF}.{(rel >> 8) & 0xFF}")
    if sw:
        parts.append(f"({str(sw)[:8]})")
    return " ".join(parts) if len(parts) > 1 else None


_VEHICLE_TYPES = {1: "rotary wing", 2: "fixed wing", 3: "rover", 4: "airship"}


def _vehicle(info, status) -> str | None:
    hw = info.get("ver_hw")
    kind = None
    if status is not None and len(status["timestamp"]):
        if "is_vtol" in status and np.any(status["is_vtol"]):
            kind = "vtol"
        elif "vehicle_type" in status:
            kind = _VEHICLE_TYPES.get(int(status["vehicle_type"][0]))
    if kind and hw:
        return f"{kind} on {hw}"
    return kind or hw


def _vehicle_type(status, params) -> tuple[str, str | None]:
    """From vehicle_status (is_vtol, system_type = MAV_TYPE, vehicle_type), else the MAV_TYPE
    parameter."""
    if status is not None and len(status["timestamp"]):
        if "is_vtol" in status and np.any(status["is_vtol"]):
            return "vtol", "vehicle_status.is_vtol"
        if "system_type" in status:
            kind, name = vehicle_from_mav_type(int(status["system_type"][0]))
            return kind, f"vehicle_status.system_type {name} ({int(status['system_type'][0])})"
        if "vehicle_type" in status:
            v = int(status["vehicle_type"][0])
            kind = {1: "multirotor", 2: "fixed-wing", 3: "rover"}.get(v, "unknown")
            return kind, f"vehicle_status.vehicle_type {v} ({_VEHICLE_TYPES.get(v, '?')})"
    return vehicle_type_from_params(params)


def _motors(b, topics, tt, params):
    if "esc_status" in topics:
        d = topics["esc_status"]
        n = int(np.max(d["esc_count"])) if "esc_count" in d and len(d["esc_count"]) else 16
        for i in range(min(max(n, 0), 16)):
            k = f"esc[{i}].esc_rpm"
            if k in d and np.any(np.nan_to_num(np.asarray(d[k], float)) != 0):
                b.add(f"rpm{i + 1}", tt(d), np.abs(np.asarray(d[k], float)), "rpm",
                      f"esc_status.{k} (|rpm|)")
    if "actuator_motors" in topics:
        d = topics["actuator_motors"]
        for i in range(16):
            k = f"control[{i}]"
            if k not in d:
                continue
            v = np.asarray(d[k], float)
            if not np.any(np.nan_to_num(v) != 0):
                continue
            if np.nanmin(v) < 0:   # reversible motors: -1..1
                b.add(f"motor{i + 1}", tt(d), (v + 1) / 2, "1", f"actuator_motors.{k} (-1..1 -> 0..1)")
            else:
                b.add(f"motor{i + 1}", tt(d), v, "1", f"actuator_motors.{k} (0..1)")
        return
    if "actuator_outputs" in topics:
        d = topics["actuator_outputs"]
        n = int(np.max(d["noutputs"])) if "noutputs" in d else 16
        add_pwm_motors(b, tt(d), [(i, f"actuator_outputs.output[{i}]", d[f"output[{i}]"])
                                  for i in range(min(n, 16)) if f"output[{i}]" in d], params)


def _status(b, topics, tt):
    if "vehicle_status" in topics:
        d = topics["vehicle_status"]
        add_arming(b, tt(d), d["arming_state"],
                   [_NAV_STATES.get(int(n), f"nav_state {int(n)}") for n in d["nav_state"]])
    if "vehicle_land_detected" in topics:
        d = topics["vehicle_land_detected"]
        add_landed(b, tt(d), d["landed"])
    else:
        b.in_flight_from_height()


def sniff(head: bytes) -> bool:
    """A ULog file starts with the magic ``ULog`` 0x01 0x12 0x35."""
    return head.startswith(b"ULog\x01\x12\x35")


READER = Reader("ulog", read_ulog, sniff, order=10, extensions=(".ulg",),
                description="PX4 ULog (.ulg), read with pyulog; NED/FRD converted to ENU/FLU")
