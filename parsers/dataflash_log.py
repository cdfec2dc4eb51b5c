"""ArduPilot DataFlash ``.bin`` logs (pymavlink ``DFReader``) -> :class:`Flight`.

What is read (old 3.x names / new 4.x names), converted from NED/FRD to ENU/FLU:

* ``ATT`` Roll/Pitch/Yaw (deg) -> roll, pitch, yaw (rad, :func:`euler_frd_ned_to_flu_enu`)
* ``EKF1`` (3.x) / ``NKF1`` / ``XKF1`` (4.x, core ``C == 0``) VN VE VD, PN PE PD -> vx vy vz, x y z.
  When a log holds both NKF1 and XKF1, the parameter ``AHRS_EKF_TYPE`` picks (else the larger).
* ``IMU`` (instance 0) GyrX..Z, AccX..Z (FRD) -> wx wy wz, ax ay az (FLU: y and z negated)
* ``RCOU`` ``Ch1..`` / ``C1..`` PWM -> motorN (0..1) through the log's ``SERVOn_FUNCTION``
  parameters (33..40 = motor1..8) and PWM range (``MOT_PWM_MIN/MAX``, else ``SERVOn_MIN/MAX``,
  else ``RC3_MIN/MAX``, else 1000-2000; see :func:`ardupilot_motor_channels`); logs without
  SERVOn_FUNCTION: channels 1..4 (or the "Frame:" message's motor count) = motors 1..4
* ``ESC`` (ESC telemetry) ``Instance``, ``RPM`` -> rpm{Instance+1} (rpm)
* ``CTUN`` ``ThrOut`` (3.x: 0..1000, detected by its range) / ``ThO`` (4.x: 0..1) -> throttle
* ``CURR`` (3.x; centivolts / centiamps when the values say so) / ``BAT`` (4.x, instance 0) -> battery
* ``GPS`` (3D fix only) Lat Lng Alt -> lat lon alt; ``BARO`` Alt -> baro_alt
* ``MODE`` -> "mode" events; ``EV`` ARMED/DISARMED/NOT_LANDED/LAND_COMPLETE and ``ARM`` -> segments
  and events; ``ERR`` -> "error" events (subsystem 12, crash check -> "crash"); ``MSG`` -> firmware.
* ``PARM`` -> the vehicle parameters droneid reads (thrust curve, command normalisation, voltage
  scaling: :data:`droneid.logs.flight.VEHICLE_PARAMETERS`) in ``Provenance.parameters``

Time: the boot clock of each message (``TimeUS`` µs or ``TimeMS`` ms; 3.x ``GPS`` uses ``T``, as
its ``TimeMS`` is GPS time of week), minus the first boot time seen. Messages without a time field
(``EV``, ``ERR``, 3.x ``MSG``) take the time of the previous timed message.
"""
from __future__ import annotations

import logging
import math
import os
import re

import numpy as np

from droneid.logs.flight import VEHICLE_PARAMETERS, Flight
from droneid.core.frames import euler_frd_ned_to_flu_enu, ned_to_enu

from ._build import (FlightBuilder, ardupilot_motor_channels, flu_columns, frame_motors, intervals_from_bool,
                     pwm_to_unit)
from ._dataflash import TypeRows, instance0, scan, timed_columns
from ._registry import Reader

log = logging.getLogger(__name__)

__all__ = ["read_dataflash", "MESSAGE_TYPES"]

#: DataFlash message types this reader asks pymavlink for.
MESSAGE_TYPES = ("ATT", "EKF1", "NKF1", "XKF1", "IMU", "RCOU", "CTUN", "CURR", "BAT", "GPS",
                 "BARO", "MODE", "EV", "ERR", "MSG", "ARM", "PARM", "ESC")

_EV_ARMED, _EV_DISARMED, _EV_LAND_COMPLETE, _EV_NOT_LANDED = 10, 11, 18, 28
_ERR_CRASH = 12
_EV_NAMES = {15: "auto armed", 17: "land complete maybe", 19: "lost GPS", 21: "flip start",
             22: "flip end", 25: "home set"}
_DEG = math.pi / 180.0

# fields wanted per type (those a given log lacks are ignored)
_WANT = {
    "ATT": ("Roll", "Pitch", "Yaw"),
    "EKF1": ("VN", "VE", "VD", "PN", "PE", "PD"),
    "NKF1": ("C", "VN", "VE", "VD", "PN", "PE", "PD"),
    "XKF1": ("C", "VN", "VE", "VD", "PN", "PE", "PD"),
    "IMU": ("I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"),
    "RCOU": tuple(f"Ch{i}" for i in range(1, 17)) + tuple(f"C{i}" for i in range(1, 17)),
    "CTUN": ("ThrOut", "ThO"),
    "CURR": ("Volt", "Curr"),
    "BAT": ("Inst", "Volt", "Curr"),
    "GPS": ("I", "Status", "Lat", "Lng", "Alt"),
    "BARO": ("I", "Alt"),
    "MODE": ("Mode", "ModeNum"),
    "EV": ("Id",),
    "ERR": ("Subsys", "ECode"),
    "MSG": ("Message",),
    "ARM": ("ArmState",),
    "PARM": ("Name", "Value"),
    "ESC": ("Instance", "RPM"),
}


#: fields a type must have to be used: a damaged FMT record can rename or drop columns
_REQUIRED = {
    "ATT": ("Roll", "Pitch", "Yaw"),
    "EKF1": ("VN", "VE", "VD", "PN", "PE", "PD"),
    "NKF1": ("VN", "VE", "VD", "PN", "PE", "PD"),
    "XKF1": ("VN", "VE", "VD", "PN", "PE", "PD"),
    "IMU": ("GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"),
    "CURR": ("Volt",), "BAT": ("Volt",),
    "GPS": ("Status", "Lat", "Lng", "Alt"),
    "BARO": ("Alt",),
    "EV": ("Id",), "ERR": ("Subsys", "ECode"), "MSG": ("Message",), "ARM": ("ArmState",),
    "PARM": ("Name", "Value"),
    "ESC": ("RPM",),
}


def _clock(mtype: str, columns: list) -> tuple[str, float] | None:
    """ArduPilot's boot clock of a message type: ``TimeUS`` (µs) or ``TimeMS`` (ms); 3.x GPS uses
    ``T`` (its TimeMS is GPS time of week); GPS with neither (time of week only) is untimed."""
    if mtype == "GPS" and "T" in columns:
        return "T", 1e-3
    if mtype == "GPS" and "TimeUS" not in columns:
        return None
    if "TimeUS" in columns:
        return "TimeUS", 1e-6
    if "TimeMS" in columns:
        return "TimeMS", 1e-3
    return None


def read_dataflash(path) -> Flight:
    """Read an ArduPilot DataFlash ``.bin`` log into a :class:`Flight` (see the module doc)."""
    path = os.fspath(path)
    b = FlightBuilder(path, "dataflash")
    types = scan(path, b, _WANT, _REQUIRED, _clock, "DataFlash log")
    data = timed_columns(path, types, "no time-stamped DataFlash messages found (empty or corrupt log)")
    params = {}
    if "PARM" in data:
        for name, value in types["PARM"].rows:
            params[name] = value
    b.parameters = {k: float(f"{params[k]:.7g}") for k in VEHICLE_PARAMETERS   # PARM holds float32
                    if k in params and isinstance(params[k], (int, float)) and math.isfinite(params[k])}

    # firmware, vehicle
    for row in types.get("MSG", TypeRows((), None)).rows:
        text = str(row[0])
        if b.firmware is None and re.search(r"(Copter|Plane|Rover|Sub|Tracker|Blimp)\s*V?\d", text):
            b.firmware = text.strip()
        m = re.match(r"Frame:\s*(\S+)", text)
        if m:
            b.vehicle = m.group(1).lower()
    if b.vehicle is None and b.firmware:
        m = re.search(r"(Copter|Plane|Rover|Sub|Tracker|Blimp)", b.firmware)
        b.vehicle = m.group(1).lower() if m else None
    b.vehicle_type, b.vehicle_declared = _vehicle_type(b.firmware, b.vehicle, params)

    if "ATT" in data:
        t, c = data["ATT"]
        r, p, y = euler_frd_ned_to_flu_enu(c["Roll"] * _DEG, c["Pitch"] * _DEG, c["Yaw"] * _DEG)
        b.add_many(t, {"roll": r, "pitch": p, "yaw": y},
                   {"roll": "rad", "pitch": "rad", "yaw": "rad"}, "ATT.Roll/Pitch/Yaw")

    ekf = _pick_ekf(data, params)
    if ekf:
        t, c = instance0(*data[ekf], "C")
        x, y, z = ned_to_enu(c["PN"], c["PE"], c["PD"])
        vx, vy, vz = ned_to_enu(c["VN"], c["VE"], c["VD"])
        b.add_many(t, {"vx": vx, "vy": vy, "vz": vz}, dict.fromkeys(("vx", "vy", "vz"), "m/s"),
                   f"{ekf}.VN/VE/VD")
        b.add_many(t, {"x": x, "y": y, "z": z}, dict.fromkeys("xyz", "m"), f"{ekf}.PN/PE/PD")

    if "IMU" in data:
        t, c = instance0(*data["IMU"], "I")
        b.add_many(t, flu_columns(("wx", "wy", "wz"), c["GyrX"], c["GyrY"], c["GyrZ"]),
                   dict.fromkeys(("wx", "wy", "wz"), "rad/s"), "IMU.GyrX/Y/Z")
        b.add_many(t, flu_columns(("ax", "ay", "az"), c["AccX"], c["AccY"], c["AccZ"]),
                   dict.fromkeys(("ax", "ay", "az"), "m/s^2"), "IMU.AccX/Y/Z")

    if "RCOU" in data:
        t, c = data["RCOU"]
        field = {int(re.sub(r"^Ch?", "", f)): f for f, v in c.items() if np.any(v > 0)}
        for ch, motor, lo, hi, how in ardupilot_motor_channels(params, field, frame_motors(b.vehicle)):
            b.add(f"motor{motor}", t, pwm_to_unit(c[field[ch]], lo, hi), "1", f"RCOU.{field[ch]} ({how})")

    if "ESC" in data:
        t, c = data["ESC"]
        inst = c.get("Instance", np.zeros(t.size))
        for i in np.unique(inst[np.isfinite(inst)]).astype(int):
            if 0 <= i < 16:
                m = inst == i
                b.add(f"rpm{i + 1}", t[m], c["RPM"][m], "rpm", f"ESC[{i}].RPM (ESC telemetry)")

    if "CTUN" in data:
        t, c = data["CTUN"]
        f = "ThO" if "ThO" in c else "ThrOut" if "ThrOut" in c else None
        if f:
            v = c[f]
            finite = v[np.isfinite(v)]
            scale = 1000.0 if finite.size and finite.max() > 1.5 else 1.0
            b.add("throttle", t, v / scale, "1", f"CTUN.{f}" + (" / 1000" if scale > 1 else ""))

    bat = "BAT" if "BAT" in data else "CURR" if "CURR" in data else None
    if bat:
        t, c = instance0(*data[bat], "Inst")
        volt, curr = c["Volt"], c.get("Curr")
        finite = volt[np.isfinite(volt)]
        scale = 100.0 if finite.size and np.median(finite) > 100.0 else 1.0
        ok = volt > 0          # 0 V: no battery monitor configured
        b.skip(f"{bat}.Volt is 0 (no battery monitor)", int((~ok).sum()))
        b.add("battery_voltage", t[ok], volt[ok] / scale, "V", f"{bat}.Volt" + (" / 100" if scale > 1 else ""))
        if curr is not None and ok.any():
            b.add("battery_current", t[ok], curr[ok] / scale, "A", f"{bat}.Curr" + (" / 100" if scale > 1 else ""))

    if "GPS" in data:
        t, c = instance0(*data["GPS"], "I")
        fix = c["Status"] >= 3
        b.skip("GPS samples without a 3D fix", int((~fix).sum()))
        if fix.any():
            b.add_many(t[fix], {"lat": c["Lat"][fix], "lon": c["Lng"][fix], "alt": c["Alt"][fix]},
                       {"lat": "deg", "lon": "deg", "alt": "m"}, "GPS.Lat/Lng/Alt")

    if "BARO" in data:
        t, c = instance0(*data["BARO"], "I")
        b.add("baro_alt", t, c["Alt"], "m", "BARO.Alt")

    _events(b, data, types)
    b.in_flight_from_height()
    return b.build()




def _vehicle_type(firmware: str | None, frame: str | None, params) -> tuple[str, str | None]:
    """From the firmware string (MSG "ArduCopter V4.6.2", "APM:Plane V3.9"): Copter ->
    multirotor (a "Frame: HELI" is not), Plane -> fixed-wing (vtol when Q_ENABLE = 1),
    Rover -> rover."""
    if not firmware:
        return "unknown", None
    m = re.search(r"(Copter|Plane|Rover|Sub|Tracker|Blimp)", firmware)
    what = m.group(1) if m else None
    decl = f"firmware {firmware!r}"
    if what == "Copter":
        if (frame or "").lower().startswith("heli"):
            return "unknown", decl + f", frame {frame}"
        return "multirotor", decl
    if what == "Plane":
        if params.get("Q_ENABLE", 0) >= 1:
            return "vtol", decl + ", Q_ENABLE = 1 (QuadPlane)"
        return "fixed-wing", decl
    if what == "Rover":
        return "rover", decl
    return "unknown", decl


def _pick_ekf(data, params):
    have = [k for k in ("XKF1", "NKF1", "EKF1") if k in data and len(data[k][0])]
    if not have:
        return None
    kind = params.get("AHRS_EKF_TYPE")
    if kind == 3 and "XKF1" in have:
        return "XKF1"
    if kind == 2 and "NKF1" in have:
        return "NKF1"
    return max(have, key=lambda k: len(data[k][0]))


def _mode_name(num: int, vehicle: str | None) -> str:
    try:
        from pymavlink import mavutil
        table = {"copter": mavutil.mode_mapping_acm, "plane": mavutil.mode_mapping_apm,
                 "rover": mavutil.mode_mapping_rover}.get(vehicle or "copter", mavutil.mode_mapping_acm)
        if vehicle and vehicle not in ("plane", "rover", "sub"):
            table = mavutil.mode_mapping_acm
        return table.get(int(num), f"mode {int(num)}")
    except Exception:  # pragma: no cover - mode names are cosmetic
        return f"mode {num}"


def _events(b: FlightBuilder, data, types):
    end = b.signals and max(s.end_s for s in b.signals.values()) or 0.0
    arm_t, arm_v = [], []
    air_t, air_v = [], []
    if "MODE" in data:
        t, c = data["MODE"]
        num = c.get("ModeNum", c.get("Mode"))
        for ti, n in zip(t, num):
            b.event(ti, "mode", _mode_name(n, b.vehicle))
    if "EV" in data:
        t, c = data["EV"]
        for ti, i in zip(t, c["Id"]):
            i = int(i)
            if i == _EV_ARMED:
                arm_t.append(ti), arm_v.append(True)
                b.event(ti, "armed")
            elif i == _EV_DISARMED:
                arm_t.append(ti), arm_v.append(False)
                air_t.append(ti), air_v.append(False)
                b.event(ti, "disarmed")
            elif i == _EV_NOT_LANDED:
                air_t.append(ti), air_v.append(True)
                b.event(ti, "takeoff")
            elif i == _EV_LAND_COMPLETE:
                air_t.append(ti), air_v.append(False)
                b.event(ti, "land")
            else:
                b.event(ti, "event", _EV_NAMES.get(i, f"EV {i}"))
    if "ARM" in data and not arm_t:
        t, c = data["ARM"]
        for ti, s in zip(t, c["ArmState"]):
            arm_t.append(ti), arm_v.append(bool(s))
            b.event(ti, "armed" if s else "disarmed")
    crash_t = None
    if "ERR" in data:
        t, c = data["ERR"]
        for ti, sub, code in zip(t, c["Subsys"], c["ECode"]):
            if int(sub) == _ERR_CRASH and int(code) != 0:
                b.event(ti, "crash", f"ERR subsystem {int(sub)} code {int(code)} (crash check)")
                crash_t = ti if crash_t is None else crash_t
            else:
                b.event(ti, "error", f"ERR subsystem {int(sub)} code {int(code)}")
    if arm_t:
        b.segment("armed", _state_intervals(arm_t, arm_v, end))
    if air_t:
        b.segment("in_flight", _state_intervals(air_t, air_v, end))
    _tilt_crash(b, crash_t)


def _state_intervals(t, v, end):
    t = np.asarray(t, float)
    v = np.asarray(v, bool)
    return intervals_from_bool(t, v, end_s=end)


def _tilt_crash(b: FlightBuilder, crash_t):
    """A 'crash' event where the vehicle, armed, tilts beyond 90 deg (flipped over)."""
    if crash_t is None and "roll" in b.signals and "pitch" in b.signals:
        crash_t = _flip_time(b)
    if crash_t is not None and "in_flight" in b.segments:
        # the flight ends at the crash: what follows is tumbling or lying on the ground
        b.segment("in_flight", tuple((a, min(c, crash_t)) for a, c in b.segments["in_flight"]
                                     if a < crash_t))


def _flip_time(b: FlightBuilder):
    r, p = b.signals["roll"], b.signals["pitch"]
    n = min(len(r), len(p))
    tilt_cos = np.cos(r.values[:n]) * np.cos(p.values[:n])
    armed = b.segments.get("armed")
    t = r.t[:n]
    mask = tilt_cos < 0.0
    if armed:
        in_arm = np.zeros(n, bool)
        for a, c in armed:
            in_arm |= (t >= a) & (t <= c)
        mask &= in_arm
    if not mask.any():
        return None
    i = int(np.flatnonzero(mask)[0])
    b.event(t[i], "crash", "attitude beyond 90 deg tilt while armed (flipped over)")
    return float(t[i])


def sniff(head: bytes) -> bool:
    """A DataFlash log starts with a message header 0xA3 0x95 (and a message type)."""
    return head[:2] == b"\xa3\x95" and len(head) >= 3


READER = Reader("dataflash", read_dataflash, sniff, order=10, extensions=(".bin",),
                description="ArduPilot DataFlash (.bin), read with pymavlink; NED/FRD converted to ENU/FLU")
