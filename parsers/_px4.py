"""PX4 conventions shared by its two log formats, ULog (:mod:`parsers.ulog_log`) and the
pre-2017 sdlog2 ``.px4log`` (:mod:`parsers.px4log`): one home for each.

* :func:`pwm_range`: the PWM range of a main output, from the log's parameters;
* :data:`ARMING_STATE_ARMED`: the arming state PX4 logs while armed (vehicle_status
  ``arming_state``, sdlog2 STAT ``ArmS``);
* :func:`vehicle_type_from_params`: the vehicle type from the ``MAV_TYPE`` parameter;
* :func:`add_attitude_quat`, :func:`add_local_ned`, :func:`add_pwm_motors`, :func:`add_battery`, :func:`add_arming`,
  :func:`add_landed`: how a PX4 attitude quaternion, PWM outputs, battery, arming state and land
  detector become signals, segments and events.

Frames (NED/FRD -> ENU/FLU) are :mod:`droneid.core.frames`', as for every reader.
"""
from __future__ import annotations

import numpy as np

from droneid.logs.flight import vehicle_from_mav_type
from droneid.core.frames import ned_to_enu, quat_flu_enu_from_frd_ned, quat_to_euler

from ._build import FlightBuilder, intervals_from_bool, pwm_formula, pwm_to_unit

__all__ = ["pwm_range", "PWM_STANDARD", "ARMING_STATE_ARMED", "vehicle_type_from_params",
           "add_attitude_quat", "add_local_ned", "add_pwm_motors", "add_battery", "add_arming", "add_landed"]

#: PX4's arming_state while armed (ARMING_STATE_ARMED), in vehicle_status and sdlog2's STAT.ArmS
ARMING_STATE_ARMED = 2

#: what a PWM source says when the log states no PWM range (the standard one is used)
PWM_STANDARD = "the standard range: the log states no PWM_MAIN_MIN/MAX"


def pwm_range(params, ch: int) -> tuple[float, float, str]:
    """PX4 PWM range of output ``ch``: PWM_MAIN_MINn/MAXn, else PWM_MAIN_MIN/MAX, else 1000-2000;
    ``(lo_us, hi_us, which parameters)``."""
    def get(kind, default):
        for key in (f"PWM_MAIN_{kind}{ch}", f"PWM_MAIN_{kind}"):
            v = params.get(key, -1)
            if v is not None and v > 0:
                return float(v), key
        return default, PWM_STANDARD
    lo, klo = get("MIN", 1000.0)
    hi, khi = get("MAX", 2000.0)
    if hi <= lo:
        return 1000.0, 2000.0, PWM_STANDARD
    return lo, hi, klo if klo == khi == PWM_STANDARD else f"{klo}/{khi}"


def vehicle_type_from_params(params) -> tuple[str, str | None]:
    """(vehicle type, declaration) from the ``MAV_TYPE`` parameter; ("unknown", None) without it."""
    if params.get("MAV_TYPE") is not None:
        kind, name = vehicle_from_mav_type(int(params["MAV_TYPE"]))
        return kind, f"parameter MAV_TYPE {name} ({int(params['MAV_TYPE'])})"
    return "unknown", None


def add_attitude_quat(b: FlightBuilder, t, q_frd_ned, source: str) -> None:
    """qw..qz (FLU body -> ENU world) and roll, pitch, yaw (Z-Y-X, from that quaternion) of a
    PX4 attitude quaternion ``(n, 4)`` that rotates FRD body vectors to NED."""
    q = quat_flu_enu_from_frd_ned(np.asarray(q_frd_ned, float))
    b.add_many(t, {"qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3]},
               dict.fromkeys(("qw", "qx", "qy", "qz"), "1"), source)
    r, p, y = quat_to_euler(q)
    b.add_many(t, {"roll": r, "pitch": p, "yaw": y}, dict.fromkeys(("roll", "pitch", "yaw"), "rad"),
               f"{source} (to Euler)")


def add_local_ned(b: FlightBuilder, t, names, ned, valid, unit: str, source: str, invalid: tuple[str, str]) -> None:
    """``names`` (ENU) from a local NED vector ``(n, e, d)``; the samples whose horizontal /
    vertical part the estimator flags invalid (``valid`` = (xy mask, z mask)) are left out and
    counted under ``invalid`` (two reasons)."""
    e, n, u = ned_to_enu(*ned)
    ok_xy, ok_z = (np.asarray(v, bool) for v in valid)
    b.skip(invalid[0], int((~ok_xy).sum()))
    b.skip(invalid[1], int((~ok_z).sum()))
    b.add(names[0], t[ok_xy], e[ok_xy], unit, source)
    b.add(names[1], t[ok_xy], n[ok_xy], unit, source)
    b.add(names[2], t[ok_z], u[ok_z], unit, source)


def add_pwm_motors(b: FlightBuilder, t, outputs, params) -> None:
    """motor{i+1} (0..1) from PWM outputs ``[(i, source, µs values)]``, through
    :func:`pwm_range`; an output that never leaves 0 is not driven and is left out."""
    for i, source, v in outputs:
        v = np.asarray(v, float)
        if np.any(v > 0):
            lo, hi, how = pwm_range(params, i + 1)
            b.add(f"motor{i + 1}", t, pwm_to_unit(v, lo, hi), "1",
                  f"{source} (PWM {lo:.0f}-{hi:.0f} us ({how}): {pwm_formula(lo, hi)})")


def add_battery(b: FlightBuilder, t, volt, curr, source: str, v_field: str, c_field: str) -> None:
    """battery_voltage (samples <= 0 V skipped and counted: no monitor) and battery_current
    (negative values, PX4's "unknown", left out)."""
    v = np.asarray(volt, float)
    ok = v > 0
    b.skip(f"{source} samples with {v_field} <= 0", int((~ok).sum()))
    b.add("battery_voltage", t[ok], v[ok], "V", f"{source}.{v_field}")
    if curr is not None:
        c = np.asarray(curr, float)
        okc = c >= 0
        b.add("battery_current", t[okc], c[okc], "A", f"{source}.{c_field}")


def add_arming(b: FlightBuilder, t, arming_state, modes) -> None:
    """"armed" segments and armed/disarmed events from PX4 arming states, and a "mode" event at
    each change of ``modes`` (mode names, one per sample)."""
    end = max((s.end_s for s in b.signals.values()), default=0.0)
    armed = np.asarray(arming_state) == ARMING_STATE_ARMED
    b.segment("armed", intervals_from_bool(t, armed, end_s=end))
    prev_a, prev_n = False, None
    for ti, a, n in zip(t, armed, modes):
        if a != prev_a:
            b.event(ti, "armed" if a else "disarmed")
            prev_a = a
        if n != prev_n:
            b.event(ti, "mode", n)
            prev_n = n


def add_landed(b: FlightBuilder, t, landed) -> None:
    """"in_flight" segments and takeoff/land events from PX4's land detector (landed flags)."""
    end = max((s.end_s for s in b.signals.values()), default=0.0)
    air = ~np.asarray(landed).astype(bool)
    b.segment("in_flight", intervals_from_bool(t, air, end_s=end))
    prev = False
    for ti, a in zip(t, air):
        if a != prev:
            b.event(ti, "takeoff" if a else "land")
            prev = a
