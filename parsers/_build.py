"""Shared pieces of every reader: collect numpy columns into a :class:`Flight`.

Readers gather raw columns (lists or arrays) per source message, convert them to the internal
convention, and hand them to :class:`FlightBuilder`, which cleans each signal (non-finite values,
duplicate or backwards stamps: skipped and counted), derives velocity from position when needed,
and turns boolean "armed" samples into segments.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from droneid.errors import LogFormatError
from droneid.logs.flight import Diagnostics, Event, Flight, Provenance, Signal
from droneid.core.frames import frd_to_flu

log = logging.getLogger(__name__)

#: |time| beyond this many seconds from the log start is damage, not data (~3 years)
MAX_TIME_S = 1e8

__all__ = ["FlightBuilder", "intervals_from_bool", "central_difference", "pwm_to_unit", "pwm_formula",
           "ardupilot_motor_channels", "ARDUPILOT_MOTOR_FUNCTIONS", "ARDUCOPTER_FRAME_MOTORS", "frame_motors",
           "command_to_unit", "flu_columns"]


def flu_columns(names: tuple[str, str, str], x, y, z) -> dict:
    """``{names[i]: component}`` of an FRD body vector (rates, accelerations) in FLU
    (:func:`droneid.core.frames.frd_to_flu`), ready for :meth:`FlightBuilder.add_many`."""
    return dict(zip(names, frd_to_flu(x, y, z)))


def pwm_to_unit(pwm, lo: float = 1000.0, hi: float = 2000.0) -> np.ndarray:
    """Servo PWM in µs (``lo``..``hi``, default 1000..2000) to 0..1 (clipped); 0 µs (output off)
    becomes 0."""
    return np.clip((np.asarray(pwm, float) - lo) / (hi - lo), 0.0, 1.0)


def pwm_formula(lo: float, hi: float) -> str:
    """How :func:`pwm_to_unit` maps PWM µs to 0..1, as text: ``"(PWM - 1000)/900 -> 0..1"``."""
    return f"(PWM - {lo:.0f})/{hi - lo:.0f} -> 0..1"


def command_to_unit(v) -> tuple[np.ndarray, str]:
    """A motor / throttle command column to 0..1, judged by the range its values SHOW (never
    assumed): within 0..1 as is; within 0..100 (above 1) as percent; every non-zero value within
    800..2200 as servo PWM in µs with the standard 1000-2000 µs range; integers within 0..255 as
    8-bit counts; within 0..65535 as 16-bit counts (e.g. the Crazyflie's motor PWM); any other
    range is kept as logged. Returns the values and a statement of the range seen and the
    normalisation applied (for the signal's source)."""
    v = np.asarray(v, float)
    fin = v[np.isfinite(v)]
    if not fin.size:
        return v, "no finite values"
    lo, hi = float(fin.min()), float(fin.max())
    seen = f"values {lo:.6g}..{hi:.6g}"
    eps = 1e-9
    if lo < -eps:
        return v, f"{seen}: negative, no known command range; kept as logged"
    if hi <= 1 + eps:
        return v, f"{seen}: a 0..1 command, used as is"
    if hi <= 100 + eps:
        return v / 100.0, f"{seen}: percent, /100 -> 0..1"
    on = fin[fin > 0]
    if on.size and on.min() >= 800 - eps and hi <= 2200 + eps:
        return pwm_to_unit(v), (f"{seen}: servo PWM 1000-2000 us (the standard range; the log states "
                                f"none), {pwm_formula(1000, 2000)}")
    integral = bool(np.all(fin == np.round(fin)))
    if integral and hi <= 255 + eps:
        return v / 255.0, f"{seen}: 8-bit counts, /255 -> 0..1"
    if hi > 255 and hi <= 65535 + eps:
        return v / 65535.0, f"{seen}: 16-bit counts, /65535 -> 0..1"
    return v, f"{seen}: no known command range (0..1, 0..100 %, 1000-2000 us, 0..255 or 0..65535 counts); kept as logged"


#: ArduPilot SERVOn_FUNCTION values of motors: 33..40 = motor1..8, 82..85 = motor9..12
ARDUPILOT_MOTOR_FUNCTIONS = {**{33 + i: i + 1 for i in range(8)}, **{82 + i: 9 + i for i in range(4)}}


#: motors of an ArduCopter frame, by the name in the log's "Frame: QUAD" message (lower case)
ARDUCOPTER_FRAME_MOTORS = {"quad": 4, "hexa": 6, "octa": 8, "octaquad": 8, "y6": 6, "tri": 3, "deca": 10,
                           "dodecahexa": 12}


def frame_motors(frame: str | None) -> int:
    """Motors of an ArduCopter frame name (default 4: a quad)."""
    return ARDUCOPTER_FRAME_MOTORS.get((frame or "").lower(), 4)


def ardupilot_motor_channels(params, channels, n_default: int = 4):
    """ArduPilot output channels that drive motors: ``[(channel, motor, lo_us, hi_us, how)]``.

    ``params`` are the log's parameters (DataFlash PARM, MAVLink PARAM_VALUE), ``channels`` the
    1-based output channels present. The motor of a channel is its ``SERVOn_FUNCTION``
    (:data:`ARDUPILOT_MOTOR_FUNCTIONS`); logs without SERVOn_FUNCTION (before ArduPilot 3.5)
    take channels 1..``n_default`` as motors 1..``n_default`` (a quad), which ``how`` says.
    The PWM range is ``MOT_PWM_MIN``/``MOT_PWM_MAX`` when set (non-zero), else the channel's
    ``SERVOn_MIN``/``SERVOn_MAX``, else ``RC3_MIN``/``RC3_MAX`` (ArduCopter 3.x drives its
    motors over the throttle channel's range), else 1000-2000 µs.
    """
    params = params or {}
    out = []
    has_func = any(f"SERVO{c}_FUNCTION" in params for c in channels)
    mot_lo, mot_hi = params.get("MOT_PWM_MIN", 0) or 0, params.get("MOT_PWM_MAX", 0) or 0
    for c in sorted(channels):
        if has_func:
            motor = ARDUPILOT_MOTOR_FUNCTIONS.get(int(params.get(f"SERVO{c}_FUNCTION", 0) or 0))
            mapping = f"SERVO{c}_FUNCTION"
        else:
            motor = c if c <= n_default else None
            mapping = f"no SERVOn_FUNCTION in the log: channel {c} taken as motor {c} of a quad"
        if motor is None:
            continue
        if mot_lo > 0 and mot_hi > mot_lo:
            lo, hi, rng = mot_lo, mot_hi, "MOT_PWM_MIN/MAX"
        elif params.get(f"SERVO{c}_MAX", 0) > params.get(f"SERVO{c}_MIN", 0) > 0:
            lo, hi, rng = params[f"SERVO{c}_MIN"], params[f"SERVO{c}_MAX"], f"SERVO{c}_MIN/MAX"
        elif params.get("RC3_MAX", 0) > params.get("RC3_MIN", 0) > 0:
            lo, hi, rng = params["RC3_MIN"], params["RC3_MAX"], "RC3_MIN/MAX"
        else:
            lo, hi, rng = 1000.0, 2000.0, "the standard range: the log states no MOT_PWM_MIN/MAX, SERVOn_MIN/MAX or RC3_MIN/MAX"
        out.append((c, motor, float(lo), float(hi), f"PWM {lo:.0f}-{hi:.0f} us ({rng}): {pwm_formula(lo, hi)}; {mapping}"))
    return out


def central_difference(t: np.ndarray, x: np.ndarray, max_gap_factor: float = 2.5) -> np.ndarray:
    """dx/dt by central differences on an uneven grid (one-sided at the ends of each run).

    The series is split where a time step exceeds ``max_gap_factor`` times the median step
    (occlusions, dropouts): no derivative spans a gap; isolated samples get nan.
    """
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    out = np.full_like(x, np.nan)
    if t.size < 2:
        return out
    dt = np.diff(t)
    cuts = np.flatnonzero(dt > max_gap_factor * np.median(dt)) + 1
    for a, c in zip(np.concatenate([[0], cuts]), np.concatenate([cuts, [t.size]])):
        if c - a >= 2:
            out[a:c] = np.gradient(x[a:c], t[a:c])
    return out


def intervals_from_bool(t: np.ndarray, flag: np.ndarray, min_len_s: float = 0.0,
                        end_s: float | None = None) -> tuple[tuple[float, float], ...]:
    """Intervals where ``flag`` is true, from state samples ``(t, flag)``.

    A true run starts at its first true sample and ends at the first false sample after it
    (or at ``end_s`` / the last sample when the log ends while true).
    """
    t = np.asarray(t, float)
    f = np.asarray(flag, bool)
    out = []
    if t.size == 0:
        return ()
    d = np.diff(np.concatenate([[False], f, [False]]).astype(np.int8))
    starts = np.flatnonzero(d == 1)
    stops = np.flatnonzero(d == -1)
    last = t[-1] if end_s is None else max(end_s, t[-1])
    for a, b in zip(starts, stops):
        t0 = t[a]
        t1 = t[b] if b < t.size else last
        if t1 - t0 >= min_len_s:
            out.append((float(t0), float(t1)))
    return tuple(out)


class FlightBuilder:
    """Accumulates signals, events, segments and diagnostics for one file."""

    def __init__(self, path, fmt: str):
        self.path = str(path)
        self.format = fmt
        self.signals: dict[str, Signal] = {}
        self.events: list[Event] = []
        self.segments: dict[str, tuple[tuple[float, float], ...]] = {}
        self.skipped: dict[str, int] = {}
        self.warnings: list[str] = []
        self.notes: list[str] = []
        self.vehicle: str | None = None
        self.firmware: str | None = None
        self.vehicle_type: str = "unknown"          # one of droneid.logs.flight.VEHICLE_TYPES
        self.vehicle_declared: str | None = None    # the raw declaration it came from
        self.parameters: dict[str, float] = {}      # the vehicle parameters the log declares (kept: VEHICLE_PARAMETERS)

    # -- diagnostics ---------------------------------------------------------------------
    def skip(self, reason: str, n: int = 1) -> None:
        if n:
            self.skipped[reason] = self.skipped.get(reason, 0) + int(n)

    def warn(self, text: str) -> None:
        # kept as data; read_flight logs one summary warning per damaged file (a quiet terminal)
        log.info("%s: %s", self.path, text)
        self.warnings.append(text)

    # -- signals -------------------------------------------------------------------------
    def add(self, name: str, t, values, unit: str, source: str) -> None:
        """Add one signal (cleaned; what is dropped is counted as '<source>: <reason>')."""
        t = np.asarray(t, float)
        values = np.asarray(values, float)
        if t.size == 0:
            return
        wild = np.abs(t) > MAX_TIME_S        # a damaged or nonsense stamp (1e300) breaks ordering
        if wild.any():
            self.skip(f"{name}: time stamps beyond {MAX_TIME_S:.0e} s from the log start", int(wild.sum()))
            t, values = t[~wild], values[~wild]
        sig, dropped = Signal.clean(name, t, values, unit, source)
        for reason, n in dropped.items():
            self.skip(f"{name}: {reason}", n)
        if len(sig):
            self.signals[name] = sig

    def add_many(self, t, columns: dict, units: dict, source: str) -> None:
        for name, v in columns.items():
            self.add(name, t, v, units[name], source)

    def event(self, t_s: float, kind: str, text: str = "") -> None:
        self.events.append(Event(float(t_s), kind, text))

    def segment(self, label: str, intervals: Sequence[tuple[float, float]]) -> None:
        self.segments[label] = tuple(intervals)

    # -- finishing -----------------------------------------------------------------------
    def derive_velocity(self) -> None:
        """vx, vy, vz from x, y, z by central differences when velocity is missing."""
        done = []
        for p, v in (("x", "vx"), ("y", "vy"), ("z", "vz")):
            if v not in self.signals and p in self.signals and len(self.signals[p]) >= 3:
                s = self.signals[p]
                self.add(v, s.t, central_difference(s.t, s.values), "m/s", f"d/dt {s.source}")
                done.append(v)
        if done:
            self.notes.append(f"{', '.join(done)} derived from position by central differences "
                              f"(not across gaps longer than 2.5 sample steps)")

    def in_flight_from_height(self, min_rise_m: float = 0.3, min_len_s: float = 1.0) -> None:
        """'in_flight' where armed and z is at least ``min_rise_m`` above the take-off level
        (a low percentile of z while armed). Needs "armed" segments: without them (mocap,
        truncated logs) whether the vehicle flies is left undetermined."""
        armed = self.segments.get("armed")
        if "in_flight" in self.segments or "z" not in self.signals or armed is None:
            return
        z = self.signals["z"]
        if len(z) < 3:
            return
        mask = np.zeros(len(z), bool)
        for a, b in armed:
            mask |= (z.t >= a) & (z.t <= b)
        if not mask.any():
            self.segments["in_flight"] = ()
            return
        ground = float(np.percentile(z.values[mask], 2))
        flying = intervals_from_bool(z.t, mask & (z.values > ground + min_rise_m), min_len_s=min_len_s)
        # a flight ends at the latest with its armed interval
        flying = tuple((a, min(b, next((e for s, e in armed if s <= a <= e), b))) for a, b in flying)
        self.segments["in_flight"] = flying
        self.notes.append(f"in_flight: armed and z more than {min_rise_m} m above "
                          f"the take-off level {ground:.2f} m")

    def build(self, *, min_signals: int = 1) -> Flight:
        if len(self.signals) < min_signals:
            detail = ""
            if self.skipped:
                detail = " (" + ", ".join(f"{k}: {n}" for k, n in self.skipped.items()) + ")"
            raise LogFormatError(self.path, f"no usable {self.format} signals found{detail}")
        self.derive_velocity()
        prov = Provenance(files=(self.path,), format=self.format, vehicle=self.vehicle,
                          firmware=self.firmware, notes=tuple(self.notes),
                          vehicle_type=self.vehicle_type, vehicle_declared=self.vehicle_declared,
                          signal_sources=tuple((n, s.unit, s.source) for n, s in self.signals.items()),
                          parameters=tuple(sorted(self.parameters.items())))
        diag = Diagnostics(self.skipped, tuple(self.warnings))
        return Flight(self.signals, prov, diag, self.segments, tuple(self.events))

