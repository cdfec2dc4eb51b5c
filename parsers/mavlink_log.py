"""MAVLink telemetry logs (``.tlog``: 8-byte big-endian µs UNIX time stamp + one MAVLink v1/v2
frame, repeated) -> :class:`Flight`.

Frames are split here and only the wanted message ids are decoded with pymavlink's
``ardupilotmega`` v2 dialect (which also decodes v1 frames); of each decoded message only the
fields in :data:`FIELDS` are kept, as numbers, so no message objects outlive the loop. Bad CRCs, unknown ids, garbage bytes
and a frame cut by the end of the file are skipped and counted.

Vehicle: several systems share a tlog (the GCS sends HEARTBEATs too, radios send RADIO_STATUS).
The vehicle is the system id whose HEARTBEAT has a vehicle ``type`` (not GCS, tracker, gimbal,
camera, onboard computer, ...) and a valid autopilot, with the most heartbeats; ``sysid=`` overrides.

Time: the tlog's own time stamps (when the GCS logged each frame), in seconds from the first frame
of the file. They exist for every message and never reset on a vehicle reboot; they carry the
radio link's jitter (tens of ms), small next to the 1-10 Hz telemetry rates. Several messages
logged with the same stamp keep the first (counted as duplicate stamps).

Read (all NED/FRD converted to ENU/FLU):
ATTITUDE (roll pitch yaw, body rates), ATTITUDE_QUATERNION (qw..qz), LOCAL_POSITION_NED (x y z,
vx vy vz), GLOBAL_POSITION_INT (lat lon alt; its NED cm/s velocity only when LOCAL_POSITION_NED is
absent), HIGHRES_IMU > SCALED_IMU > RAW_IMU (first present; RAW_IMU is assumed to use ArduPilot's
scaling, milli-g and milli-rad/s, as ArduPilot sends it; PX4 never sends RAW_IMU in that form),
SERVO_OUTPUT_RAW (port 0, PWM -> motorN 0..1 through SERVOn_FUNCTION and the PWM range from the
PARAM_VALUE messages when the GCS fetched them, see :func:`ardupilot_motor_channels`),
ESC_TELEMETRY_1_TO_4 / _5_TO_8 rpm -> rpm1..8, ATTITUDE_TARGET thrust (0..1) -> throttle, else VFR_HUD
throttle (% -> 0..1), SYS_STATUS battery
(mV, cA; the "unknown" values 0/65535 and -1 are skipped) else BATTERY_STATUS, HEARTBEAT (armed
flag -> "armed" segments, custom mode -> "mode" events), EXTENDED_SYS_STATE landed_state ->
"in_flight", STATUSTEXT -> firmware string.
"""
from __future__ import annotations

import logging
import os
import re
from operator import attrgetter
from types import SimpleNamespace

import numpy as np

from droneid.errors import LogFormatError
from droneid.logs.flight import Flight, vehicle_from_mav_type
from droneid.core.frames import euler_frd_ned_to_flu_enu, ned_to_enu, quat_flu_enu_from_frd_ned

from ._build import FlightBuilder, ardupilot_motor_channels, frame_motors, intervals_from_bool, pwm_to_unit
from ._registry import Reader

log = logging.getLogger(__name__)

__all__ = ["read_tlog", "MESSAGE_NAMES", "FIELDS", "iter_frames"]

MESSAGE_NAMES = ("HEARTBEAT", "ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED",
                 "GLOBAL_POSITION_INT", "HIGHRES_IMU", "SCALED_IMU", "RAW_IMU", "SERVO_OUTPUT_RAW",
                 "VFR_HUD", "SYS_STATUS", "BATTERY_STATUS", "EXTENDED_SYS_STATE", "STATUSTEXT",
                 "ESC_TELEMETRY_1_TO_4", "ESC_TELEMETRY_5_TO_8", "ATTITUDE_TARGET", "PARAM_VALUE")

_IMU_FIELDS = ("xacc", "yacc", "zacc", "xgyro", "ygyro", "zgyro")
#: message -> fields kept (as numbers) when the frame is decoded; nothing else is stored
FIELDS = {
    "HEARTBEAT": ("type", "autopilot", "base_mode", "custom_mode"),
    "ATTITUDE": ("roll", "pitch", "yaw", "rollspeed", "pitchspeed", "yawspeed"),
    "ATTITUDE_QUATERNION": ("q1", "q2", "q3", "q4"),
    "LOCAL_POSITION_NED": ("x", "y", "z", "vx", "vy", "vz"),
    "GLOBAL_POSITION_INT": ("lat", "lon", "alt", "vx", "vy", "vz"),
    "HIGHRES_IMU": _IMU_FIELDS, "SCALED_IMU": _IMU_FIELDS, "RAW_IMU": _IMU_FIELDS,
    "SERVO_OUTPUT_RAW": ("port",) + tuple(f"servo{i}_raw" for i in range(1, 17)),
    "VFR_HUD": ("throttle",),
    "SYS_STATUS": ("voltage_battery", "current_battery"),
    "BATTERY_STATUS": ("voltage0", "current_battery"),
    "EXTENDED_SYS_STATE": ("landed_state",),
    "STATUSTEXT": ("text",),
    "ESC_TELEMETRY_1_TO_4": tuple(f"rpm[{i}]" for i in range(4)),
    "ESC_TELEMETRY_5_TO_8": tuple(f"rpm[{i}]" for i in range(4)),
    "ATTITUDE_TARGET": ("thrust",),
    "PARAM_VALUE": ("param_id", "param_value"),
}
_TEXT_MESSAGES = ("STATUSTEXT", "PARAM_VALUE")


def _getter(name):
    if name == "BATTERY_STATUS":
        return lambda m: (m.voltages[0], m.current_battery)
    if name.startswith("ESC_TELEMETRY_"):
        return lambda m: tuple(m.rpm)
    fields = FIELDS[name]
    return attrgetter(*fields) if len(fields) > 1 else (lambda m, f=fields[0]: (getattr(m, f),))


# MAV_TYPE values that are not a vehicle
_NOT_VEHICLE = {0, 5, 6, 18, 26, 27, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42}
_MAV_AUTOPILOT_INVALID = 8
_MAV_MODE_FLAG_SAFETY_ARMED = 128
_VEHICLE_NAMES = {1: "fixed wing", 2: "quadrotor", 3: "coaxial", 4: "helicopter", 10: "ground rover",
                  11: "surface boat", 12: "submarine", 13: "hexarotor", 14: "octorotor",
                  15: "tricopter", 19: "vtol", 20: "vtol", 21: "vtol", 22: "vtol", 23: "vtol",
                  24: "vtol", 25: "vtol", 29: "dodecarotor"}
_AUTOPILOT_NAMES = {3: "ArduPilot", 12: "PX4"}
_T_MIN_US, _T_MAX_US = 946684800_000000, 4102444800_000000  # years 2000 .. 2100


def _dialect():
    from pymavlink.dialects.v20 import ardupilotmega as mav  # v2 dialect parses v1 frames too
    return mav


def iter_frames(data: bytes, counts: dict):
    """Yield ``(t_us, msgid, frame_bytes)`` for each MAVLink frame of a tlog buffer.

    Garbage is skipped byte by byte until a plausible ``timestamp + magic`` is found; the skipped
    bytes and a final frame cut by the end of the buffer are counted in ``counts``.
    """
    n = len(data)
    pos = 0
    last_t = None
    garbage = 0
    while pos + 10 <= n:
        magic = data[pos + 8]
        t_us = int.from_bytes(data[pos:pos + 8], "big")
        ok_t = _T_MIN_US < t_us < _T_MAX_US and (last_t is None or abs(t_us - last_t) < 86_400_000_000)
        if magic == 0xFE and ok_t:
            flen = data[pos + 9] + 8
            if pos + 8 + flen > n:
                counts["frame cut by the end of the file"] = counts.get("frame cut by the end of the file", 0) + 1
                break
            frame = data[pos + 8:pos + 8 + flen]
            msgid = frame[5]
        elif magic == 0xFD and ok_t and pos + 11 <= n:
            flen = data[pos + 9] + 12 + (13 if data[pos + 10] & 1 else 0)
            if pos + 8 + flen > n:
                counts["frame cut by the end of the file"] = counts.get("frame cut by the end of the file", 0) + 1
                break
            frame = data[pos + 8:pos + 8 + flen]
            msgid = frame[7] | (frame[8] << 8) | (frame[9] << 16)
        else:
            pos += 1
            garbage += 1
            continue
        last_t = t_us
        yield t_us, msgid, frame
        pos += 8 + flen
    if garbage:
        counts["garbage bytes between frames"] = counts.get("garbage bytes between frames", 0) + garbage


def read_tlog(path, sysid: int | None = None) -> Flight:
    """Read a MAVLink ``.tlog`` into a :class:`Flight` (see the module doc)."""
    path = os.fspath(path)
    mav = _dialect()
    with open(path, "rb") as f:
        data = f.read()
    if not data:
        raise LogFormatError(path, "the file is empty")
    ids = {getattr(mav, f"MAVLINK_MSG_ID_{name}"): name for name in MESSAGE_NAMES}
    getters = {name: _getter(name) for name in MESSAGE_NAMES}
    parser = mav.MAVLink(None)
    counts: dict[str, int] = {}
    rows: dict[tuple[int, str], list] = {}
    times: dict[tuple[int, str], list] = {}
    t_first = None
    n_frames = 0
    for t_us, msgid, frame in iter_frames(data, counts):
        n_frames += 1
        if t_first is None:
            t_first = t_us
        name = ids.get(msgid)
        if name is None:
            continue
        try:
            m = parser.decode(bytearray(frame))
        except mav.MAVError as exc:
            reason = "bad CRC" if "CRC" in str(exc) else "undecodable frame"
            counts[reason] = counts.get(reason, 0) + 1
            continue
        key = (m.get_srcSystem(), name)
        rows.setdefault(key, []).append(getters[name](m))
        times.setdefault(key, []).append(t_us)
    if n_frames == 0:
        raise LogFormatError(path, "no MAVLink frames found (not a tlog, or corrupt from the start)")
    b = FlightBuilder(path, "tlog")
    for k, v in counts.items():
        b.skip(k, v)
    vid = _vehicle_sysid(rows, sysid, path)
    msgs = {name: (np.asarray(times[(s, name)], float) - t_first) * 1e-6
            for (s, name) in rows if s == vid}
    get = {name: _table(name, rows[(vid, name)]) for name in msgs}
    _convert(b, msgs, get)
    return b.build()


def _vehicle_sysid(rows, sysid, path) -> int:
    systems = sorted({s for s, _ in rows})
    if sysid is not None:
        if sysid not in systems:
            raise LogFormatError(path, f"system id {sysid} sends no wanted messages; "
                                       f"system ids in the log: {systems}")
        return int(sysid)
    best, n_best = None, 0
    for (s, name), ms in rows.items():
        if name != "HEARTBEAT":
            continue
        n = sum(1 for typ, autopilot, *_ in ms if typ not in _NOT_VEHICLE and autopilot != _MAV_AUTOPILOT_INVALID)
        if n > n_best:
            best, n_best = s, n
    if best is None:
        # no vehicle heartbeat: the system with the most wanted messages
        if not rows:
            raise LogFormatError(path, "no vehicle messages (ATTITUDE, LOCAL_POSITION_NED, ...) found")
        per = {}
        for (s, _), ms in rows.items():
            per[s] = per.get(s, 0) + len(ms)
        best = max(per, key=per.get)
    return int(best)


def _table(name: str, rows: list) -> dict:
    """Field tuples of one message type -> {field: column} (numbers as float arrays)."""
    cols = {}
    for f, col in zip(FIELDS[name], zip(*rows)):
        cols[f] = np.asarray(col, dtype=object if name in _TEXT_MESSAGES and f != "param_value" else float)
    return cols


def _col(tab, field, scale=1.0):
    return tab[field] * scale


def _convert(b: FlightBuilder, t, get):
    rad = dict.fromkeys(("roll", "pitch", "yaw"), "rad")
    if "STATUSTEXT" in get:
        for text in get["STATUSTEXT"]["text"]:
            text = str(text)
            if b.firmware is None and re.search(r"(Copter|Plane|Rover|Sub|PX4)\S*\s*V?\d", text):
                b.firmware = text.strip()
            fm = re.match(r"Frame:\s*(\S+)", text)
            if fm:
                b.vehicle = fm.group(1).lower()
    if "ATTITUDE" in get:
        ms, tt = get["ATTITUDE"], t["ATTITUDE"]
        r, p, y = euler_frd_ned_to_flu_enu(_col(ms, "roll"), _col(ms, "pitch"), _col(ms, "yaw"))
        b.add_many(tt, {"roll": r, "pitch": p, "yaw": y}, rad, "ATTITUDE.roll/pitch/yaw")
        b.add_many(tt, {"wx": _col(ms, "rollspeed"), "wy": -_col(ms, "pitchspeed"),
                        "wz": -_col(ms, "yawspeed")}, dict.fromkeys(("wx", "wy", "wz"), "rad/s"),
                   "ATTITUDE.rollspeed/pitchspeed/yawspeed")
    if "ATTITUDE_QUATERNION" in get:
        ms, tt = get["ATTITUDE_QUATERNION"], t["ATTITUDE_QUATERNION"]
        q = np.stack([_col(ms, a) for a in ("q1", "q2", "q3", "q4")], axis=-1)
        q = quat_flu_enu_from_frd_ned(q)
        b.add_many(tt, {"qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3]},
                   dict.fromkeys(("qw", "qx", "qy", "qz"), "1"), "ATTITUDE_QUATERNION.q1..q4")
    if "LOCAL_POSITION_NED" in get:
        ms, tt = get["LOCAL_POSITION_NED"], t["LOCAL_POSITION_NED"]
        x, y, z = ned_to_enu(_col(ms, "x"), _col(ms, "y"), _col(ms, "z"))
        vx, vy, vz = ned_to_enu(_col(ms, "vx"), _col(ms, "vy"), _col(ms, "vz"))
        b.add_many(tt, {"x": x, "y": y, "z": z}, dict.fromkeys("xyz", "m"), "LOCAL_POSITION_NED.x/y/z")
        b.add_many(tt, {"vx": vx, "vy": vy, "vz": vz}, dict.fromkeys(("vx", "vy", "vz"), "m/s"),
                   "LOCAL_POSITION_NED.vx/vy/vz")
    if "GLOBAL_POSITION_INT" in get:
        ms, tt = get["GLOBAL_POSITION_INT"], t["GLOBAL_POSITION_INT"]
        lat, lon = _col(ms, "lat", 1e-7), _col(ms, "lon", 1e-7)
        valid = (lat != 0) | (lon != 0)
        b.skip("GLOBAL_POSITION_INT without a position (lat = lon = 0)", int((~valid).sum()))
        b.add_many(tt[valid], {"lat": lat[valid], "lon": lon[valid], "alt": _col(ms, "alt", 1e-3)[valid]},
                   {"lat": "deg", "lon": "deg", "alt": "m"}, "GLOBAL_POSITION_INT.lat/lon/alt")
        if "vx" not in b.signals:
            vx, vy, vz = ned_to_enu(_col(ms, "vx", 0.01), _col(ms, "vy", 0.01), _col(ms, "vz", 0.01))
            b.add_many(tt, {"vx": vx, "vy": vy, "vz": vz}, dict.fromkeys(("vx", "vy", "vz"), "m/s"),
                       "GLOBAL_POSITION_INT.vx/vy/vz")
    _imu(b, t, get)
    params = {}
    if "PARAM_VALUE" in get:
        for pid, val in zip(get["PARAM_VALUE"]["param_id"], get["PARAM_VALUE"]["param_value"]):
            params[str(pid).rstrip("\x00")] = float(val)
    if "SERVO_OUTPUT_RAW" in get:
        ms, tt = get["SERVO_OUTPUT_RAW"], t["SERVO_OUTPUT_RAW"]
        port0 = ms["port"] == 0
        present = [i for i in range(1, 17) if np.any(ms[f"servo{i}_raw"][port0] > 0)]
        for ch, motor, lo, hi, how in ardupilot_motor_channels(params, present, frame_motors(b.vehicle)):
            attr = f"servo{ch}_raw"
            b.add(f"motor{motor}", tt[port0], pwm_to_unit(ms[attr][port0], lo, hi), "1",
                  f"SERVO_OUTPUT_RAW.{attr} ({how})")
    for name, first in (("ESC_TELEMETRY_1_TO_4", 1), ("ESC_TELEMETRY_5_TO_8", 5)):
        if name in get:
            for i in range(4):
                v = get[name][f"rpm[{i}]"]
                if np.any(v > 0):
                    b.add(f"rpm{first + i}", t[name], v, "rpm", f"{name}.rpm[{i}]")
    thrust = get.get("ATTITUDE_TARGET", {}).get("thrust")
    if thrust is not None and np.any(np.nan_to_num(thrust) > 0):
        b.add("throttle", t["ATTITUDE_TARGET"], thrust, "1", "ATTITUDE_TARGET.thrust (0..1)")
    elif "VFR_HUD" in get:
        b.add("throttle", t["VFR_HUD"], _col(get["VFR_HUD"], "throttle", 0.01), "1", "VFR_HUD.throttle / 100")
    _battery(b, t, get)
    if "EXTENDED_SYS_STATE" in get:
        ms, tt = get["EXTENDED_SYS_STATE"], t["EXTENDED_SYS_STATE"]
        landed = _col(ms, "landed_state")
        if np.any(landed > 0):  # 0 = undefined
            b.segment("in_flight", intervals_from_bool(tt, landed == 2))
    if "HEARTBEAT" in get:      # last: the armed interval may run to the last sample of any signal
        _heartbeat(b, t["HEARTBEAT"], get["HEARTBEAT"])
    b.in_flight_from_height()


def _imu(b, t, get):
    for name, acc_scale, gyro_scale in (("HIGHRES_IMU", 1.0, 1.0),
                                         ("SCALED_IMU", 9.80665e-3, 1e-3),
                                         ("RAW_IMU", 9.80665e-3, 1e-3)):
        if name not in get:
            continue
        ms, tt = get[name], t[name]
        b.add_many(tt, {"ax": _col(ms, "xacc", acc_scale), "ay": -_col(ms, "yacc", acc_scale),
                        "az": -_col(ms, "zacc", acc_scale)}, dict.fromkeys(("ax", "ay", "az"), "m/s^2"),
                   f"{name}.xacc/yacc/zacc" + (" (milli-g)" if acc_scale != 1 else ""))
        if "wx" not in b.signals or name == "HIGHRES_IMU":
            b.add_many(tt, {"wx": _col(ms, "xgyro", gyro_scale), "wy": -_col(ms, "ygyro", gyro_scale),
                            "wz": -_col(ms, "zgyro", gyro_scale)}, dict.fromkeys(("wx", "wy", "wz"), "rad/s"),
                       f"{name}.xgyro/ygyro/zgyro" + (" (mrad/s)" if gyro_scale != 1 else ""))
        if name == "RAW_IMU":
            b.notes.append("RAW_IMU assumed in ArduPilot's scaling: milli-g and milli-rad/s")
        return


def _battery(b, t, get):
    if "SYS_STATUS" in get:
        ms, tt = get["SYS_STATUS"], t["SYS_STATUS"]
        v = _col(ms, "voltage_battery")
        ok = (v > 0) & (v < 65535)
        b.skip("SYS_STATUS battery voltage unknown (0 or 65535)", int((~ok).sum()))
        if ok.any():
            b.add("battery_voltage", tt[ok], v[ok] * 1e-3, "V", "SYS_STATUS.voltage_battery / 1000")
        c = _col(ms, "current_battery")
        ok = c >= 0
        if ok.any():
            b.add("battery_current", tt[ok], c[ok] * 1e-2, "A", "SYS_STATUS.current_battery / 100")
    if "battery_voltage" not in b.signals and "BATTERY_STATUS" in get:
        ms, tt = get["BATTERY_STATUS"], t["BATTERY_STATUS"]
        v = ms["voltage0"]
        ok = (v > 0) & (v < 65535)
        if ok.any():
            b.add("battery_voltage", tt[ok], v[ok] * 1e-3, "V", "BATTERY_STATUS.voltages[0] / 1000")
        c = _col(ms, "current_battery")
        ok = c >= 0
        if ok.any() and "battery_current" not in b.signals:
            b.add("battery_current", tt[ok], c[ok] * 1e-2, "A", "BATTERY_STATUS.current_battery / 100")


def _heartbeat(b: FlightBuilder, tt, hb):
    valid = ~np.isin(hb["type"], list(_NOT_VEHICLE))
    if not valid.any():
        return
    tt = tt[valid]
    typ, autopilot = hb["type"][valid].astype(int), hb["autopilot"][valid].astype(int)
    base, custom = hb["base_mode"][valid].astype(int), hb["custom_mode"][valid].astype(int)
    b.vehicle = b.vehicle or _VEHICLE_NAMES.get(typ[0], f"MAV_TYPE {typ[0]}")
    b.vehicle_type, name = vehicle_from_mav_type(typ[0])
    b.vehicle_declared = f"HEARTBEAT type {name} ({typ[0]})"
    if b.firmware is None and autopilot[0] in _AUTOPILOT_NAMES:
        b.firmware = _AUTOPILOT_NAMES[autopilot[0]]
    armed = (base & _MAV_MODE_FLAG_SAFETY_ARMED) != 0
    end = max((s.end_s for s in b.signals.values()), default=float(tt[-1]))
    b.segment("armed", intervals_from_bool(tt, armed, end_s=max(end, float(tt[-1]))))
    prev_armed = None
    prev_mode = None
    for i, ti in enumerate(tt):
        a = bool(armed[i])
        if a != prev_armed:
            if prev_armed is not None or a:
                b.event(ti, "armed" if a else "disarmed")
            prev_armed = a
        mode = _mode_string(int(typ[i]), int(autopilot[i]), int(base[i]), int(custom[i]))
        if mode != prev_mode:
            b.event(ti, "mode", mode)
            prev_mode = mode


def _mode_string(typ: int, autopilot: int, base_mode: int, custom_mode: int) -> str:
    hb = SimpleNamespace(type=typ, autopilot=autopilot, base_mode=base_mode, custom_mode=custom_mode,
                         get_type=lambda: "HEARTBEAT")
    try:
        from pymavlink import mavutil
        return str(mavutil.mode_string_v10(hb))
    except Exception:  # pragma: no cover - cosmetic
        return f"custom_mode {custom_mode}"


def sniff(head: bytes) -> bool:
    """MAVLink frames, each after an 8-byte big-endian µs UNIX time stamp, make up most of the
    head of the file (a few garbage bytes are tolerated; the reader counts them)."""
    if len(head) < 10:
        return False
    pos, frames, garbage = 0, 0, 0
    n = len(head)
    while pos + 10 <= n:
        magic = head[pos + 8]
        ts = int.from_bytes(head[pos:pos + 8], "big")
        if magic in (0xFE, 0xFD) and 946684800_000000 < ts < 4102444800_000000:  # 2000..2100
            ln = head[pos + 9] + (8 if magic == 0xFE else 12)
            if magic == 0xFD and pos + 10 < n and head[pos + 10] & 1:
                ln += 13
            frames += 1
            pos += 8 + ln
        else:
            pos += 1
            garbage += 1
    return frames >= 1 and garbage <= 0.25 * max(pos, 1) and (frames >= 2 or n < 64)


READER = Reader("tlog", read_tlog, sniff, order=20, extensions=(".tlog",), options=("sysid",),
                description="MAVLink telemetry log (.tlog), read with pymavlink; NED/FRD converted "
                            "to ENU/FLU")
