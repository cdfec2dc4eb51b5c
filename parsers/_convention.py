"""The user's statement of a log's convention, applied once at the reader boundary (issue 41).

Readers take a flat CSV's or an MCAP's values as droneid's convention (ENU world, FLU body,
seconds, SI). When a log is not, the reader options say what it is and :func:`convert` turns the
read flight into droneid's convention; :mod:`droneid.logs.consistency` names the option to use:

* ``scale={"vx": "1/3.6"}`` (``--scale NAME=FACTOR``, repeatable): multiply a signal as read by a
  factor (a number, ``a/b``, ``pi``: ``1/3.6`` for km/h, ``pi/180`` for degrees, ``-1`` for a
  sign). Scaling ``roll``, ``pitch`` or ``yaw`` rebuilds the quaternion from the scaled angles
  (``--scale yaw=-1`` for a heading that turns clockwise).
* ``world_frame="ned"`` (``--world-frame``): the position and velocity are north, east, down:
  ``(x, y, z) = (E, N, -D)`` (:func:`droneid.core.frames.ned_to_enu`).
* ``body_frame="frd"`` (``--body-frame``): the body rates and accelerations are forward, right,
  down: y and z negated. With ``world_frame="ned"`` as well, the attitude is that of an FRD body
  in NED and is converted too (:func:`droneid.core.frames.euler_frd_ned_to_flu_enu`,
  :func:`droneid.core.frames.quat_flu_enu_from_frd_ned`); with one of the two alone the attitude is
  taken as FLU in ENU.
* ``time_unit="ms"`` (``--time-unit {s,ms,us,ns}``): the time stamps the reader took as seconds
  are in that unit; every stamp, segment and event is scaled.

Order: scale (on the signals as the reader named them), frames, time. Velocity the reader derived
from position is derived again from the converted position. Each conversion is noted in the
flight's provenance.
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from droneid.errors import ConfigError, check_choice, did_you_mean
from droneid.logs.flight import TIME_UNITS, Flight, Signal
from droneid.core.frames import (BODY_FRAMES, WORLD_FRAMES, euler_frd_ned_to_flu_enu, euler_to_quat, ned_to_enu,
                            quat_flu_enu_from_frd_ned, quat_to_euler, wrap_angle)

from ._build import central_difference

__all__ = ["convert", "parse_factor"]

_NUM = r"(pi|[0-9]*\.?[0-9]+(?:e[-+]?[0-9]+)?)"
_FACTOR = re.compile(rf"^([-+]?)\s*{_NUM}\s*(?:/\s*{_NUM})?$", re.I)
_EULER = ("roll", "pitch", "yaw")
_QUAT = ("qw", "qx", "qy", "qz")


def parse_factor(text) -> float:
    """A scale factor: a number, ``pi``, or ``a/b`` of those, with a sign (``1/3.6``, ``pi/180``,
    ``-1``); ConfigError otherwise."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value = float(text)
    else:
        m = _FACTOR.match(str(text).strip())
        if not m:
            raise ConfigError(f"--scale: the factor must be a number, pi or a/b (e.g. 1/3.6, pi/180, -1). "
                              f"Got {text!r} instead.")
        sign, a, b = m.groups()

        def num(s):
            return math.pi if s.lower() == "pi" else float(s)
        den = num(b) if b else 1.0
        value = (-1.0 if sign == "-" else 1.0) * num(a) / den if den else math.nan
    if not (math.isfinite(value) and value != 0):
        raise ConfigError(f"--scale: the factor must be finite and non-zero. Got {text!r} instead.")
    return value


def convert(flight: Flight, *, world_frame: str | None = None, body_frame: str | None = None,
            time_unit: str | None = None, scale: Mapping[str, object] | None = None) -> Flight:
    """``flight`` as read, turned into droneid's convention by the user's statement of the log's
    own (see the module doc); unchanged when every option is None or the default."""
    if world_frame is not None:
        check_choice("world_frame", world_frame, WORLD_FRAMES, "read_flight")
    if body_frame is not None:
        check_choice("body_frame", body_frame, BODY_FRAMES, "read_flight")
    if time_unit is not None:
        check_choice("time_unit", time_unit, tuple(TIME_UNITS), "read_flight")
    factors = {str(k): parse_factor(v) for k, v in (scale or {}).items()}
    ned, frd = world_frame == "ned", body_frame == "frd"
    per_s = TIME_UNITS[time_unit or "s"]
    if not factors and not ned and not frd and per_s == 1.0:
        return flight
    sig = dict(flight.signals)
    notes = []
    if factors:
        _scale(sig, factors, flight)
        notes.append("scaled as told (--scale): " + ", ".join(f"{k} x {v:.6g}" for k, v in factors.items()))
    if ned:
        for a, b, c in (("x", "y", "z"), ("vx", "vy", "vz")):
            if all(n in sig for n in (a, b, c)) and _same_t(sig, (a, b, c)):
                # as read: a = north, b = east, c = down
                e, n_, u = ned_to_enu(sig[a].values, sig[b].values, sig[c].values)
                sig[a], sig[b], sig[c] = (_with(sig[a], e), _with(sig[b], n_), _with(sig[c], u))
            else:
                for name, other in ((a, b), (b, a)):
                    if name in sig and other not in sig:
                        raise ConfigError(f"--world-frame ned: {name} without {other}: cannot swap north and east")
                if a in sig:
                    sig[a], sig[b] = _with(sig[b], sig[b].values, name=a), _with(sig[a], sig[a].values, name=b)
                if c in sig:
                    sig[c] = _with(sig[c], -sig[c].values)
        notes.append("world frame NED as told (--world-frame ned): (x, y, z) = (east, north, -down)")
    if frd:
        for n in ("wy", "wz", "ay", "az"):
            if n in sig:
                sig[n] = _with(sig[n], -sig[n].values)
        notes.append("body frame FRD as told (--body-frame frd): y and z of the rates and accelerations negated")
    if ned and frd:
        if all(n in sig for n in _QUAT) and _same_t(sig, _QUAT):
            q = quat_flu_enu_from_frd_ned(np.column_stack([sig[n].values for n in _QUAT]))
            for i, n in enumerate(_QUAT):
                sig[n] = _with(sig[n], q[:, i])
            r, p, y = quat_to_euler(q)
            t = sig["qw"].t
            for n, v in zip(_EULER, (r, p, y)):
                sig[n] = Signal(n, t, v, "rad", sig["qw"].source + " (to Euler)")
        elif all(n in sig for n in _EULER) and _same_t(sig, _EULER):
            r, p, y = euler_frd_ned_to_flu_enu(*(sig[n].values for n in _EULER))
            for n, v in zip(_EULER, (r, p, y)):
                sig[n] = _with(sig[n], v)
        notes.append("attitude of an FRD body in NED converted to FLU in ENU")
    if per_s != 1.0:
        sig = {k: replace(s, t=s.t * per_s) for k, s in sig.items()}
        notes.append(f"time stamps in {time_unit} as told (--time-unit {time_unit}): x {per_s:g} to seconds")
    for p, v in (("x", "vx"), ("y", "vy"), ("z", "vz")):
        if v in sig and sig[v].source.startswith("d/dt") and p in sig:
            s = sig[p]
            sig[v] = Signal(v, s.t, central_difference(s.t, s.values), "m/s", f"d/dt {s.source}")
    out = replace(flight, signals=sig)
    if per_s != 1.0:
        out = replace(out, segments={k: tuple((a * per_s, b * per_s) for a, b in v) for k, v in flight.segments.items()},
                      events=tuple(replace(e, t_s=e.t_s * per_s) for e in flight.events))
    prov = out.provenance
    for n in notes:
        prov = prov.with_note(n)
    return replace(out, provenance=prov)


def _with(s: Signal, values, name: str | None = None) -> Signal:
    return Signal(name or s.name, s.t, values, s.unit, s.source)


def _same_t(sig, names) -> bool:
    t0 = sig[names[0]].t
    return all(sig[n].t.shape == t0.shape and np.array_equal(sig[n].t, t0) for n in names[1:])


def _scale(sig: dict, factors: dict, flight: Flight) -> None:
    """Multiply the named signals in place; Euler angles rebuild the quaternion."""
    for name, k in factors.items():
        if name not in sig:
            raise ConfigError(f"--scale: no signal {name!r} in {flight.name}" + did_you_mean(name, sig)
                              + f" (signals: {', '.join(sig)})")
        if name in _QUAT:
            raise ConfigError(f"--scale: a quaternion component ({name}) cannot be scaled; scale roll, pitch or yaw")
    euler = [n for n in factors if n in _EULER]
    for name, k in factors.items():
        if name not in _EULER:
            sig[name] = _with(sig[name], sig[name].values * k)
    if not euler:
        return
    if all(n in sig for n in _QUAT) and _same_t(sig, _QUAT):
        q = np.column_stack([sig[n].values for n in _QUAT])
        angles = dict(zip(_EULER, quat_to_euler(q)))
        for n in euler:
            angles[n] = angles[n] * factors[n]
        q2 = euler_to_quat(*(angles[n] for n in _EULER))
        q2 = np.where(q2[:, :1] < 0, -q2, q2)
        t, src = sig["qw"].t, sig["qw"].source
        for i, n in enumerate(_QUAT):
            sig[n] = _with(sig[n], q2[:, i])
        r, p, y = quat_to_euler(q2)
        for n, v in zip(_EULER, (r, p, y)):
            sig[n] = Signal(n, t, v, "rad", src + " (to Euler)")
    else:
        for n in euler:
            v = sig[n].values * factors[n]
            sig[n] = _with(sig[n], wrap_angle(v) if n == "yaw" else v)
