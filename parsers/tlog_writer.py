"""Write a :class:`Flight` as a MAVLink 2 telemetry log (``.tlog``), encoded with pymavlink.

Each record is an 8-byte big-endian UNIX time stamp in µs followed by one packed MAVLink 2 frame
(system 1, component 1, sequence counting up). Time stamps are ``EPOCH (2024-01-01 UTC) + t``,
never the wall clock, so the same flight always gives the same bytes; ``time_boot_ms`` /
``time_usec`` are the flight's seconds. The first HEARTBEAT is at t = 0, so readers that count
from the first frame recover the flight's own times. Each message is written on the time base of
its first field (e.g. ATTITUDE on roll's); other fields on other time bases are interpolated.
Euler angles or quaternion missing from the flight are derived from the other.

Messages (ENU/FLU -> NED/FRD through the involutions of :mod:`droneid.core.frames`):

========================  =========================================================================
HEARTBEAT (1 Hz)          MAV_TYPE_QUADROTOR, ArduPilot, SAFETY_ARMED inside the "armed" segments
ATTITUDE                  roll, pitch, yaw (FRD/NED), rollspeed = wx, pitchspeed = -wy, yawspeed = -wz
ATTITUDE_QUATERNION       q FRD->NED, same rates
LOCAL_POSITION_NED        x = y_enu (north), y = x_enu, z = -z; velocities alike
HIGHRES_IMU               xacc = ax, yacc = -ay, zacc = -az (specific force, FRD), gyro alike
SERVO_OUTPUT_RAW          servoN_raw = 1000 + 1000 * motorN (µs PWM); with more than 4 motors also
                          PARAM_VALUE SERVOn_FUNCTION (motorN), SERVOn_MIN = 1000, SERVOn_MAX = 2000
ESC_TELEMETRY_1_TO_4/5_8  rpm = rpm1..rpm8 (integer rpm, 0..65535)
VFR_HUD                   throttle (integer %), groundspeed, heading, alt = z, climb = vz
SYS_STATUS                voltage_battery (mV), current_battery (cA, -1 when unknown)
EXTENDED_SYS_STATE        landed_state IN_AIR inside the "in_flight" segments, else ON_GROUND
                          (on the position/attitude time base; only when the flight has segments)
========================  =========================================================================

Precision: float32 fields (~1e-7 relative), PWM 1e-3, rpm 1, throttle 1 %, voltage 1 mV, heading 1 deg.
Collective ``thrust`` (N) has no MAVLink field and is not written.
"""
from __future__ import annotations

import math
import os

import numpy as np

from droneid.core.frames import euler_frd_ned_to_flu_enu, ned_to_enu, quat_flu_enu_from_frd_ned
from droneid.core.io_util import atomic_write_bytes

from ._writer_util import EPOCH_US, complete_attitude, group, require_some

__all__ = ["write_tlog"]

_MAV_TYPE_QUADROTOR = 2
_MAV_AUTOPILOT_ARDUPILOTMEGA = 3
_FLAG_CUSTOM_MODE = 1
_FLAG_STABILIZE = 16
_FLAG_ARMED = 128
_MAV_STATE_STANDBY, _MAV_STATE_ACTIVE = 3, 4
_MAV_LANDED_STATE_ON_GROUND, _MAV_LANDED_STATE_IN_AIR = 1, 2


def _f(x):
    return float(x) if math.isfinite(x) else float("nan")


def write_tlog(flight, path) -> str:
    """Write ``flight`` to ``path`` as a MAVLink 2 ``.tlog`` (atomically); returns the path."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    path = os.fspath(path)
    require_some(flight, path, "tlog")
    flight = complete_attitude(flight)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    records: list[tuple[int, int, object]] = []   # (t_us, order, message)

    def add(t_s, order, msg):
        records.append((int(round(t_s * 1e6)), order, msg))

    # heartbeats from t = 0 (or the first sample, if earlier): readers count time from the first
    # frame, so a flight's own time origin survives the round trip
    t_start, t_end = min(0.0, flight.start_s), flight.end_s
    armed = flight.segments.get("armed", ())
    for k in range(int(math.floor(t_end - t_start)) + 1):
        ts = t_start + k
        is_armed = any(a <= ts <= b for a, b in armed)
        mode = _FLAG_CUSTOM_MODE | _FLAG_STABILIZE | (_FLAG_ARMED if is_armed else 0)
        add(ts, 0, mav.heartbeat_encode(_MAV_TYPE_QUADROTOR, _MAV_AUTOPILOT_ARDUPILOTMEGA, mode, 0,
                                        _MAV_STATE_ACTIVE if is_armed else _MAV_STATE_STANDBY))

    rates = ("wx", "wy", "wz")
    g = group(flight, ("roll", "pitch", "yaw") + rates, required=("roll", "pitch", "yaw"))
    if g:
        t, v = g
        r, p, y = euler_frd_ned_to_flu_enu(v["roll"], v["pitch"], v["yaw"])  # an involution
        pq = [np.nan_to_num(v["wx"]), -np.nan_to_num(v["wy"]), -np.nan_to_num(v["wz"])]
        for i in range(t.size):
            add(t[i], 1, mav.attitude_encode(_ms(t[i]), r[i], p[i], y[i], pq[0][i], pq[1][i], pq[2][i]))
    g = group(flight, ("qw", "qx", "qy", "qz") + rates, required=("qw", "qx", "qy", "qz"))
    if g:
        t, v = g
        q = quat_flu_enu_from_frd_ned(np.column_stack([v["qw"], v["qx"], v["qy"], v["qz"]]))
        pq = [np.nan_to_num(v["wx"]), -np.nan_to_num(v["wy"]), -np.nan_to_num(v["wz"])]
        for i in range(t.size):
            add(t[i], 2, mav.attitude_quaternion_encode(_ms(t[i]), *q[i], pq[0][i], pq[1][i], pq[2][i]))
    g = group(flight, ("x", "y", "z", "vx", "vy", "vz"), required=("x", "y", "z"))
    if g:
        t, v = g
        n, e, d = ned_to_enu(v["x"], v["y"], v["z"])          # an involution: ENU -> NED
        vn, ve, vd = ned_to_enu(v["vx"], v["vy"], v["vz"])
        for i in range(t.size):
            add(t[i], 3, mav.local_position_ned_encode(_ms(t[i]), n[i], e[i], d[i],
                                                       _f(vn[i]), _f(ve[i]), _f(vd[i])))
    g = group(flight, ("ax", "ay", "az") + rates, required=("ax", "ay", "az"))
    if g:
        t, v = g
        w = [np.nan_to_num(v["wx"]), -np.nan_to_num(v["wy"]), -np.nan_to_num(v["wz"])]
        has_gyro = all(flight.has(n) for n in rates)
        for i in range(t.size):
            add(t[i], 4, mav.highres_imu_encode(
                _us(t[i]), v["ax"][i], -v["ay"][i], -v["az"][i], w[0][i], w[1][i], w[2][i],
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0b111 | (0b111000 if has_gyro else 0)))
    motors = [f"motor{i}" for i in range(1, 17) if flight.has(f"motor{i}")]
    if motors:
        n_out = max(int(m[5:]) for m in motors)
        names = tuple(f"motor{i}" for i in range(1, n_out + 1))
        t, v = group(flight, names, required=(motors[0],))
        pwm = np.column_stack([np.where(np.isfinite(v[nm]), np.clip(np.round(1000 + 1000 * v[nm]), 0, 65535), 0)
                               for nm in names]).astype(int)
        pwm = np.pad(pwm, ((0, 0), (0, 16 - n_out)))
        for i in range(t.size):
            add(t[i], 5, mav.servo_output_raw_encode(_us(t[i]) & 0xFFFFFFFF, 0, *map(int, pwm[i])))
        # more than 4 outputs: the mapping and range the reader applies (up to 4, the readers'
        # default for logs without parameters, a quad on channels 1..4 at 1000-2000 µs, holds)
        for k in range(1, n_out + 1 if n_out > 4 else 1):
            for name, value in ((f"SERVO{k}_FUNCTION", 32 + k if k <= 8 else 73 + k),
                                (f"SERVO{k}_MIN", 1000.0), (f"SERVO{k}_MAX", 2000.0)):
                add(t_start, 0, mav.param_value_encode(name.encode(), float(value), 9, 3 * n_out, 0))
    for first, encode in ((1, mav.esc_telemetry_1_to_4_encode), (5, mav.esc_telemetry_5_to_8_encode)):
        names = tuple(f"rpm{first + k}" for k in range(4))
        present = [n for n in names if flight.has(n)]
        if not present:
            continue
        t, v = group(flight, names, required=(present[0],))
        rpm = np.column_stack([np.clip(np.round(np.nan_to_num(v[n])), 0, 65535) for n in names]).astype(int)
        zeros = [0] * 4
        for i in range(t.size):
            add(t[i], 9, encode(temperature=zeros, voltage=zeros, current=zeros, totalcurrent=zeros,
                                rpm=[int(r) for r in rpm[i]], count=zeros))
    g = group(flight, ("throttle", "vx", "vy", "vz", "z", "yaw"), required=("throttle",))
    if g:
        t, v = g
        gs = np.nan_to_num(np.hypot(v["vx"], v["vy"]))
        heading = np.nan_to_num(np.round(np.degrees(np.pi / 2 - v["yaw"])) % 360).astype(int)
        thr = np.clip(np.round(100 * v["throttle"]), 0, 100).astype(int)
        for i in range(t.size):
            add(t[i], 6, mav.vfr_hud_encode(0.0, gs[i], int(heading[i]), int(thr[i]),
                                            _f(np.nan_to_num(v["z"][i])), _f(np.nan_to_num(v["vz"][i]))))
    g = group(flight, ("battery_voltage", "battery_current"), required=("battery_voltage",))
    if g:
        t, v = g
        mv = np.clip(np.round(v["battery_voltage"] * 1000), 0, 65534).astype(int)
        ca = np.where(np.isfinite(v["battery_current"]), np.round(v["battery_current"] * 100), -1).astype(int)
        for i in range(t.size):
            add(t[i], 7, mav.sys_status_encode(0, 0, 0, 0, int(mv[i]), int(ca[i]), -1, 0, 0, 0, 0, 0, 0))

    if "in_flight" in flight.segments:
        base = next((n for n in ("x", "roll", "vx", "qw") if flight.has(n)), None)
        times = flight[base].t if base else np.array([t_start + k for k in range(int(t_end - t_start) + 1)])
        flying = flight.segments["in_flight"]
        for ts in times:
            air = any(a <= ts <= b for a, b in flying)
            add(ts, 8, mav.extended_sys_state_encode(
                0, _MAV_LANDED_STATE_IN_AIR if air else _MAV_LANDED_STATE_ON_GROUND))

    records.sort(key=lambda r: (r[0], r[1]))
    out = bytearray()
    for t_us, _, msg in records:
        out += (EPOCH_US + t_us).to_bytes(8, "big")
        out += msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
    atomic_write_bytes(path, bytes(out))
    return path


def _ms(t_s) -> int:
    return int(round(t_s * 1000.0)) & 0xFFFFFFFF


def _us(t_s) -> int:
    return int(round(t_s * 1e6))
