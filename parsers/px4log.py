"""PX4's pre-2017 sdlog2 logs (``.px4log``; pymavlink ``DFReader``) -> :class:`Flight`.

sdlog2 writes DataFlash records (the container is :mod:`parsers._dataflash`, shared with the
ArduPilot reader) with PX4's own messages, in PX4's NED/FRD frames, converted here exactly as
the ULog reader converts them (:mod:`droneid.core.frames`, :mod:`parsers._px4`):

* ``ATT`` qw..qz (FRD -> NED) -> qw..qz and roll, pitch, yaw from it, as the ULog reader does;
  a log whose quaternion is not filled in (all 0, as in early sdlog2) gives Roll/Pitch/Yaw (rad)
  -> roll, pitch, yaw (:func:`euler_frd_ned_to_flu_enu`) and no qw..qz;
  RollRate/PitchRate/YawRate (FRD) -> wx wy wz (FLU); else ``IMU`` GyroX..Z
* ``LPOS`` X Y Z, VX VY VZ (NED) -> x y z, vx vy vz (ENU); samples whose ``PFlg`` says invalid
  (bit 1 xy, 2 z, 4 v_xy, 8 v_z) are skipped and counted
* ``IMU`` (instance 0; IMU1, IMU2 are the other sensors) AccX..Z (FRD) -> ax ay az (FLU)
* ``OUT0`` Out0..Out7 (PWM µs) -> motor1..motor8 (0..1) with PX4's PWM range (as the ULog
  reader's actuator_outputs; an output that never leaves 0 is not driven and left out)
* ``ATTC`` Thrust (actuator_controls_0[3], 0..1) -> throttle
* ``BATT`` V, C -> battery_voltage, battery_current
* ``GPS`` (3D fix only) Lat Lon Alt -> lat lon alt; ``SENS`` BaroAlt -> baro_alt
* ``STAT`` ArmS (2 = armed) -> "armed" segments, MainState -> "mode" events (pymavlink's PX4
  mode names), Landed -> "in_flight" segments
* ``VER`` FwGit, Arch -> firmware, board; parameter ``MAV_TYPE`` -> vehicle type

Time: sdlog2 starts every logging cycle with a ``TIME`` record whose ``StartTime`` is the boot
clock in µs; the records of the cycle carry no time of their own and take it (pymavlink's
DFReader stamps them the same way, ``_timestamp``, but only once a GPS fix gives it a time base,
so the reader takes ``StartTime`` itself). Seconds from the first ``TIME``.
"""
from __future__ import annotations

import os
import struct

import numpy as np

from droneid.logs.flight import Flight, vehicle_from_mav_type
from droneid.core.frames import euler_frd_ned_to_flu_enu

from ._build import FlightBuilder, flu_columns
from ._dataflash import scan, timed_columns
from ._px4 import (add_arming, add_attitude_quat, add_battery, add_landed, add_local_ned, add_pwm_motors,
                   vehicle_type_from_params)
from ._registry import Reader

__all__ = ["read_px4log", "MESSAGE_TYPES"]

_OUTPUTS = tuple(f"Out{i}" for i in range(8))

# fields wanted per type (those a given log lacks are ignored)
_WANT = {
    "TIME": ("StartTime",),
    "ATT": ("qw", "qx", "qy", "qz", "Roll", "Pitch", "Yaw", "RollRate", "PitchRate", "YawRate"),
    "LPOS": ("X", "Y", "Z", "VX", "VY", "VZ", "PFlg"),
    "IMU": ("AccX", "AccY", "AccZ", "GyroX", "GyroY", "GyroZ"),
    "OUT0": _OUTPUTS,
    "ATTC": ("Thrust",),
    "BATT": ("V", "C"),
    "GPS": ("Fix", "Lat", "Lon", "Alt"),
    "SENS": ("BaroAlt",),
    "STAT": ("MainState", "ArmS", "Landed"),
    "VER": ("Arch", "FwGit"),
    "PARM": ("Name", "Value"),
}

#: fields a type must have to be used: a damaged FMT record can rename or drop columns
_REQUIRED = {
    "TIME": ("StartTime",),
    "ATT": ("Roll", "Pitch", "Yaw"),
    "LPOS": ("X", "Y", "Z", "VX", "VY", "VZ"),
    "IMU": ("AccX", "AccY", "AccZ"),
    "ATTC": ("Thrust",),
    "BATT": ("V",),
    "GPS": ("Fix", "Lat", "Lon", "Alt"),
    "SENS": ("BaroAlt",),
    "STAT": ("ArmS",),
    "PARM": ("Name", "Value"),
}

#: sdlog2 message types this reader asks pymavlink for
MESSAGE_TYPES = tuple(_WANT)

#: LPOS.PFlg bits (sdlog2: xy_valid 1, z_valid 2, v_xy_valid 4, v_z_valid 8)
_XY, _Z, _VXY, _VZ = 1, 2, 4, 8


def _clock(mtype: str, cols: list) -> tuple[str, float] | None:
    """Only ``TIME`` carries a time (``StartTime``, µs of the boot clock)."""
    return ("StartTime", 1e-6) if mtype == "TIME" and "StartTime" in cols else None


def read_px4log(path) -> Flight:
    """Read a PX4 sdlog2 ``.px4log`` into a :class:`Flight` (see the module doc)."""
    path = os.fspath(path)
    b = FlightBuilder(path, "px4log")
    types = scan(path, b, _WANT, _REQUIRED, _clock, "PX4 sdlog2 log")
    data = timed_columns(path, types, "no TIME records (the clock of a PX4 sdlog2 log) found: "
                                      "empty or corrupt log")
    params = {name: value for name, value in types["PARM"].rows} if "PARM" in types else {}
    b.vehicle_type, b.vehicle_declared = vehicle_type_from_params(params)
    _version(b, data.get("VER"), params)

    if "ATT" in data:
        _attitude(b, *data["ATT"])
    if "LPOS" in data:
        _local_position(b, *data["LPOS"])
    if "IMU" in data:
        t, c = data["IMU"]
        b.add_many(t, flu_columns(("ax", "ay", "az"), c["AccX"], c["AccY"], c["AccZ"]),
                   dict.fromkeys(("ax", "ay", "az"), "m/s^2"), "IMU.AccX/Y/Z")
        if "wx" not in b.signals and {"GyroX", "GyroY", "GyroZ"} <= c.keys():
            b.add_many(t, flu_columns(("wx", "wy", "wz"), c["GyroX"], c["GyroY"], c["GyroZ"]),
                       dict.fromkeys(("wx", "wy", "wz"), "rad/s"), "IMU.GyroX/Y/Z")
    if "OUT0" in data:
        t, c = data["OUT0"]
        add_pwm_motors(b, t, [(i, f"OUT0.{k}", c[k]) for i, k in enumerate(_OUTPUTS) if k in c], params)
    if "ATTC" in data:
        t, c = data["ATTC"]
        b.add("throttle", t, c["Thrust"], "1", "ATTC.Thrust (actuator_controls_0[3], 0..1)")
    if "BATT" in data:
        t, c = data["BATT"]
        add_battery(b, t, c["V"], c.get("C"), "BATT", "V", "C")
    if "GPS" in data:
        t, c = data["GPS"]
        fix = c["Fix"] >= 3
        b.skip("GPS samples without a 3D fix", int((~fix).sum()))
        b.add_many(t[fix], {"lat": c["Lat"][fix], "lon": c["Lon"][fix], "alt": c["Alt"][fix]},
                   {"lat": "deg", "lon": "deg", "alt": "m"}, "GPS.Lat/Lon/Alt")
    if "SENS" in data:
        t, c = data["SENS"]
        b.add("baro_alt", t, c["BaroAlt"], "m", "SENS.BaroAlt")
    _status(b, data.get("STAT"))
    return b.build()


def _version(b: FlightBuilder, ver, params) -> None:
    """Firmware "PX4 (44d2c4a1)" from VER.FwGit; vehicle "octorotor on PX4FMU_V2" from the
    parameter MAV_TYPE and VER.Arch."""
    arch = git = None
    if ver is not None and len(ver[0]):
        _, c = ver
        arch, git = (str(c[k][0]).strip() or None if k in c else None for k in ("Arch", "FwGit"))
    b.firmware = f"PX4 ({git[:8]})" if git else None
    kind = None
    if params.get("MAV_TYPE") is not None:
        kind = vehicle_from_mav_type(int(params["MAV_TYPE"]))[1].removeprefix("MAV_TYPE_").lower()
    b.vehicle = f"{kind} on {arch}" if kind and arch else kind or arch


def _attitude(b: FlightBuilder, t, c) -> None:
    q = np.column_stack([c[k] for k in ("qw", "qx", "qy", "qz")]) if {"qw", "qx", "qy", "qz"} <= c.keys() else None
    if q is not None and np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) < 1e-2):
        add_attitude_quat(b, t, q, "ATT.qw/qx/qy/qz")
    else:
        r, p, y = euler_frd_ned_to_flu_enu(c["Roll"], c["Pitch"], c["Yaw"])
        b.add_many(t, {"roll": r, "pitch": p, "yaw": y}, dict.fromkeys(("roll", "pitch", "yaw"), "rad"),
                   "ATT.Roll/Pitch/Yaw")
    if {"RollRate", "PitchRate", "YawRate"} <= c.keys():
        b.add_many(t, flu_columns(("wx", "wy", "wz"), c["RollRate"], c["PitchRate"], c["YawRate"]),
                   dict.fromkeys(("wx", "wy", "wz"), "rad/s"), "ATT.RollRate/PitchRate/YawRate")


def _local_position(b: FlightBuilder, t, c) -> None:
    flags = c["PFlg"].astype(np.int64) if "PFlg" in c else np.full(t.size, _XY | _Z | _VXY | _VZ)
    for names, fields, (bxy, bz), unit in ((("x", "y", "z"), ("X", "Y", "Z"), (_XY, _Z), "m"),
                                           (("vx", "vy", "vz"), ("VX", "VY", "VZ"), (_VXY, _VZ), "m/s")):
        add_local_ned(b, t, names, [c[f] for f in fields], ((flags & bxy) != 0, (flags & bz) != 0), unit,
                      f"LPOS.{'/'.join(fields)}",
                      (f"LPOS samples whose PFlg marks {'/'.join(fields[:2])} invalid",
                       f"LPOS samples whose PFlg marks {fields[2]} invalid"))


def _status(b: FlightBuilder, stat) -> None:
    if stat is None or not len(stat[0]):
        b.in_flight_from_height()
        return
    from pymavlink import mavutil  # wrapped here: pymavlink reads globals at import
    t, c = stat
    main = c.get("MainState", np.full(t.size, np.nan))
    add_arming(b, t, c["ArmS"], [mavutil.mode_string_px4(int(m)) if m == m else "unknown" for m in main])
    if "Landed" in c:
        add_landed(b, t, c["Landed"])
    else:
        b.in_flight_from_height()


#: an FMT record: header, FMT type, then type, length, name, format, columns
_FMT = struct.Struct("<3sBB4s16s64s")


def sniff(head: bytes) -> bool:
    """An sdlog2 log starts with FMT records (0xA3 0x95 0x80) like an ArduPilot DataFlash log,
    but never describes FMT itself first (ArduPilot always does) and stamps no message with
    ``TimeUS``/``TimeMS`` (sdlog2 stamps cycles with a TIME record)."""
    cols, name0 = [], None
    for ofs in range(0, len(head) - _FMT.size + 1, _FMT.size):
        hdr, _, _, name, _, col = _FMT.unpack_from(head, ofs)
        if hdr != b"\xa3\x95\x80":
            break
        if name0 is None:
            name0 = name.rstrip(b"\0")
        cols.extend(col.rstrip(b"\0").split(b","))
    return (name0 is not None and name0 != b"FMT" and b"TimeUS" not in cols and b"TimeMS" not in cols)


READER = Reader("px4log", read_px4log, sniff, order=9, extensions=(".px4log",),
                description="PX4 sdlog2 log (.px4log, before 2017), read with pymavlink; NED/FRD "
                            "converted to ENU/FLU")
