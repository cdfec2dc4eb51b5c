"""Is a set of flights fit for identifying a model? Checked BEFORE any fitting (issue 13).

:func:`assess` looks at each flight's declared vehicle type, airborne time, the rates of the
signals the model needs, how many grid samples remain at the sampling period, and how much the
flight excites the model (tilt, horizontal speed, yaw). It returns a :class:`Fitness` holding
the measurements, ``problems`` (refusals; each one line saying how to override) and
``warnings`` (marginal data). Pure: nothing is printed; :meth:`Fitness.raise_if_refused` raises
a :class:`~droneid.errors.DataError` with the first problem.

Thresholds (module constants, documented with their reason):

=============================  ===============================================================
``MIN_RATE_STEPS = 0.25``      a needed signal logged slower than ``1 / (4 Ts)`` is refused:
                               three grid points in four would be interpolation, and the
                               derivative of velocity would be a staircase of the log's steps
``1 / Ts``                     slower than one sample per grid step: a warning (the grid is
                               finer than the data; derivatives are smoothed by interpolation)
``SLOW_DYNAMICS_HZ = 5``       below 5 Hz a warning whatever Ts: multirotor tilt/drag dynamics
                               (time constants ~0.3-1 s) are barely resolved
``MIN_AIRBORNE_S = 10``        less airborne time: a warning; none at all: refused
``MIN_SAMPLES = 50``           fewer grid samples in flight (all flights): refused
``MIN_TILT_RANGE_DEG = 3``     tilt, horizontal speed and yaw that hardly vary leave the model's
``MIN_SPEED_RANGE_MS = 1``     terms collinear or constant: a warning each
``MIN_YAW_SPAN_DEG = 20``
``MAX_SPAN_S = 172800``        a log spanning more than 2 days has damaged stamps: no airborne data
=============================  ===============================================================

Vehicle: a multirotor prior on a log that declares a fixed-wing or a rover is refused; a VTOL,
or a log that declares nothing (mocap CSV, MCAP), is a warning. ``vehicle=`` (the user's
``--vehicle``) replaces every flight's declaration.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .dataset_builder import in_flight_intervals, resample_signal
from .errors import DataError, check_choice
from .flight import VEHICLE_TYPES, Flight
from .targets import state_of

__all__ = ["assess", "check_prior_data", "usable_signals", "Fitness", "FlightFitness", "TILT_DRAG_SIGNALS",
           "ROTOR_THRUST_SIGNALS"]

MIN_RATE_STEPS = 0.25
SLOW_DYNAMICS_HZ = 5.0
MIN_AIRBORNE_S = 10.0
MIN_SAMPLES = 50
MIN_TILT_RANGE_DEG = 3.0
MIN_SPEED_RANGE_MS = 1.0
MIN_YAW_SPAN_DEG = 20.0
#: a flight longer than this (2 days) has damaged time stamps: not scanned for airborne time
MAX_SPAN_S = 172_800.0

#: signals of the tilt-drag prior (vx_dot, vy_dot from tilt and velocity)
TILT_DRAG_SIGNALS = ("vx", "vy", "roll", "pitch", "yaw")
#: signals of a rotor-thrust model of vz_dot (plus one rotor signal: rpm1, motor1 or throttle)
ROTOR_THRUST_SIGNALS = ("vz", "roll", "pitch")

#: vehicle types (flight.VEHICLE_TYPES) a prior's vehicle kind (priors.base.VEHICLE_KINDS)
#: accepts without comment / refuses; the kinds not listed (ground, any) are not checked
_ACCEPTS = {"multirotor": ("multirotor",), "fixed-wing": ("fixed-wing",)}
_REFUSES = {"multirotor": ("fixed-wing", "rover"), "fixed-wing": ("multirotor", "rover")}


@dataclass(frozen=True)
class FlightFitness:
    """Measurements of one flight (seconds, Hz, degrees, m/s)."""
    name: str
    vehicle_type: str
    vehicle_declared: str | None
    airborne_s: float
    airborne_notes: tuple[str, ...]
    rates_hz: Mapping[str, float]           # median rate of each needed signal; nan when absent
    samples: int                            # grid samples at ts inside the airborne intervals
    tilt_deg: tuple[float, float]           # (min, max) of max(|roll|, |pitch|) while airborne
    speed_ms: tuple[float, float]           # (min, max) horizontal speed while airborne
    yaw_span_deg: float                     # max - min of the unwrapped yaw while airborne

    def __post_init__(self):
        object.__setattr__(self, "rates_hz", MappingProxyType(dict(self.rates_hz)))


@dataclass(frozen=True)
class Fitness:
    """The verdict of :func:`assess`: per-flight measurements, refusals and warnings."""
    flights: tuple[FlightFitness, ...]
    needed_signals: tuple[str, ...]
    ts: float
    prior_kind: str
    problems: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    thresholds: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({
        "min_rate_steps": MIN_RATE_STEPS, "slow_dynamics_hz": SLOW_DYNAMICS_HZ,
        "min_airborne_s": MIN_AIRBORNE_S, "min_samples": MIN_SAMPLES,
        "min_tilt_range_deg": MIN_TILT_RANGE_DEG, "min_speed_range_ms": MIN_SPEED_RANGE_MS,
        "min_yaw_span_deg": MIN_YAW_SPAN_DEG}))

    @property
    def ok(self) -> bool:
        """True when nothing is refused (warnings may remain)."""
        return not self.problems

    def raise_if_refused(self) -> None:
        """Raise :class:`DataError` with the first problem (and how many more) if any."""
        if self.problems:
            more = f" (and {len(self.problems) - 1} more problem(s))" if len(self.problems) > 1 else ""
            raise DataError(self.problems[0] + more)

    def to_dict(self) -> dict:
        """A JSON-ready dict (non-finite numbers as None)."""
        return {
            "ok": self.ok, "prior_kind": self.prior_kind, "ts": self.ts,
            "needed_signals": list(self.needed_signals),
            "problems": list(self.problems), "warnings": list(self.warnings),
            "thresholds": dict(self.thresholds),
            "flights": [{
                "name": f.name, "vehicle_type": f.vehicle_type, "vehicle_declared": f.vehicle_declared,
                "airborne_s": _r(f.airborne_s), "airborne_notes": list(f.airborne_notes),
                "rates_hz": {k: _r(v) for k, v in f.rates_hz.items()}, "samples": f.samples,
                "tilt_deg": [_r(x) for x in f.tilt_deg], "speed_ms": [_r(x) for x in f.speed_ms],
                "yaw_span_deg": _r(f.yaw_span_deg)} for f in self.flights],
        }


def _r(x, nd=3):
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def assess(flights: Flight | Sequence[Flight], *, needed_signals: Sequence[str], ts: float,
           prior_kind: str = "multirotor", vehicle: str | None = None) -> Fitness:
    """Judge whether ``flights`` can identify a ``prior_kind`` model of ``needed_signals`` on a
    grid of ``ts`` seconds (see the module doc for the thresholds).

    ``vehicle`` (one of :data:`droneid.flight.VEHICLE_TYPES`) overrides each flight's declared
    vehicle type, as ``--vehicle`` does.
    """
    if isinstance(flights, Flight):
        flights = [flights]
    if not flights:
        raise DataError("assess: no flights given")
    if not (isinstance(ts, (int, float)) and ts > 0 and math.isfinite(ts)):
        raise DataError(f"The 'ts' parameter of assess must be a positive number of seconds. "
                        f"Got {ts!r} instead.")
    check_choice("prior_kind", prior_kind, tuple(_ACCEPTS), "assess")
    if vehicle is not None:
        check_choice("vehicle", vehicle, VEHICLE_TYPES, "assess")
    needed = tuple(needed_signals)
    problems: list[str] = []
    warnings: list[str] = []
    out = []
    total_samples = 0
    for f in flights:
        name = f.name
        vtype = vehicle or f.provenance.vehicle_type
        declared = (f"--vehicle {vehicle}" if vehicle else f.provenance.vehicle_declared)
        _vehicle_verdict(name, vtype, declared, prior_kind, problems, warnings)

        rates = {s: (f[s].rate_hz if f.has(s) else math.nan) for s in needed}
        for s in needed:
            if not f.has(s):
                problems.append(f"{name}: signal '{s}' is missing: choose other inputs or map a "
                                f"column/topic to it (--column {s}=..., --topic {s}=...)")
        ivs, notes = _airborne(f, ts, in_flight_intervals)
        airborne = float(sum(b - a for a, b in ivs))
        samples = int(sum(math.floor((b - a) / ts) + 1 for a, b in ivs if b > a))
        total_samples += samples
        if airborne <= 0:
            problems.append(f"{name}: no airborne data ({'; '.join(notes) or 'no in-flight interval'}): "
                            f"use a log of a flight, or choose the part to use (droneid dataset --in-flight all / --window)")
        elif airborne < MIN_AIRBORNE_S:
            warnings.append(f"{name}: only {airborne:.1f} s airborne (< {MIN_AIRBORNE_S:.0f} s): "
                            f"expect loose estimates")
        _rate_verdict(name, rates, ts, problems, warnings)
        tilt, speed, yaw_span = _excitation(f, ivs, resample_signal)
        if airborne > 0:
            if math.isfinite(tilt[1]) and tilt[1] - tilt[0] < MIN_TILT_RANGE_DEG:
                warnings.append(f"{name}: tilt varies by {tilt[1] - tilt[0]:.1f} deg only "
                                f"(< {MIN_TILT_RANGE_DEG:g}): little excitation of the tilt terms")
            if math.isfinite(speed[1]) and speed[1] - speed[0] < MIN_SPEED_RANGE_MS:
                warnings.append(f"{name}: horizontal speed varies by {speed[1] - speed[0]:.2f} m/s only "
                                f"(< {MIN_SPEED_RANGE_MS:g}): little excitation of the drag terms")
            if math.isfinite(yaw_span) and yaw_span < MIN_YAW_SPAN_DEG:
                warnings.append(f"{name}: yaw spans {yaw_span:.0f} deg only (< {MIN_YAW_SPAN_DEG:g}): "
                                f"body and world axes stay aligned")
        out.append(FlightFitness(name, vtype, declared, airborne, tuple(notes), rates, samples,
                                 tilt, speed, yaw_span))
    if 0 < total_samples < MIN_SAMPLES:
        problems.append(f"only {total_samples} samples in flight at Ts = {ts:g} s "
                        f"(< {MIN_SAMPLES}): use more or longer flights")
    return Fitness(tuple(out), needed, float(ts), prior_kind, tuple(problems), tuple(warnings))


def _rate_verdict(name, rates, ts, problems, warnings) -> None:
    """One line per kind of rate trouble, listing the signals (slowest first)."""
    known = sorted(((hz, s) for s, hz in rates.items() if math.isfinite(hz)))
    refused = [(hz, s) for hz, s in known if hz * ts < MIN_RATE_STEPS]
    coarse = [(hz, s) for hz, s in known if MIN_RATE_STEPS <= hz * ts < 0.95]   # 5 % jitter
    slow = [(hz, s) for hz, s in known if hz < SLOW_DYNAMICS_HZ and hz * ts >= MIN_RATE_STEPS]

    def listing(items):
        return ", ".join(f"{s} {hz:.1f} Hz" for hz, s in items)
    if refused:
        hz, s = refused[0]
        problems.append(
            f"{name}: {s} is logged at {hz:.1f} Hz, below 1/(4 Ts) = {MIN_RATE_STEPS / ts:.0f} Hz "
            f"for Ts = {ts:g} s (2/Ts = {2 / ts:.0f} Hz is ideal): use --ts "
            f"{_nice(MIN_RATE_STEPS / hz)} or more, or a log with faster {s}"
            + (f" (also slow: {listing(refused[1:])})" if len(refused) > 1 else ""))
    if coarse:
        warnings.append(f"{name}: logged slower than the grid (1/Ts = {1 / ts:.0f} Hz), grid values "
                        f"between samples are interpolated: {listing(coarse)}")
    if slow:
        warnings.append(f"{name}: below {SLOW_DYNAMICS_HZ:.0f} Hz, multirotor dynamics are barely "
                        f"resolved: {listing(slow)}")


def _nice(x: float) -> str:
    for step in (0.05, 0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0):
        if x <= step:
            return f"{step:g}"
    return f"{x:.0f}"


def _vehicle_verdict(name, vtype, declared, prior_kind, problems, warnings) -> None:
    said = f" ({declared})" if declared else ""
    what = {"multirotor": "multirotor (quadrotor)"}.get(prior_kind, prior_kind)
    if vtype in _REFUSES.get(prior_kind, ()):
        problems.append(f"{name}: {what} prior on a {vtype} log{said}: pass --vehicle "
                        f"{prior_kind} to override")
    elif vtype == "unknown":
        warnings.append(f"{name}: vehicle type unknown{said or ' (the log does not declare it)'}: "
                        f"a {what} is assumed; pass --vehicle to state it")
    elif vtype not in _ACCEPTS.get(prior_kind, ()):
        warnings.append(f"{name}: {what} prior on a {vtype} log{said}: only its "
                        f"{'hover' if vtype == 'vtol' else 'matching'} phases follow the prior")


def _airborne(f: Flight, ts: float, in_flight_intervals):
    if f.duration_s > MAX_SPAN_S:
        return [], [f"a time span of {f.duration_s:.3g} s is not a flight (damaged time stamps?)"]
    if "armed" in f.segments and not f.segments["armed"]:
        return [], ["never armed (the log's armed state is false throughout)"]
    ivs, notes = in_flight_intervals(f, ts=ts)
    return [(a, b) for a, b in ivs if b > a], list(notes)


def _excitation(f: Flight, ivs, resample_signal):
    nan2 = (math.nan, math.nan)
    if not ivs:
        return nan2, nan2, math.nan
    step = 0.1
    t = np.concatenate([np.arange(a, b, step) for a, b in ivs if b - a >= step] or [np.empty(0)])
    if t.size == 0:
        return nan2, nan2, math.nan

    def on_grid(name):
        if not f.has(name):
            return None
        s = f[name]
        inside = (t >= s.start_s) & (t <= s.end_s)
        v = np.full(t.size, np.nan)
        v[inside] = resample_signal(s, t[inside])
        return v

    def rng(v):
        v = v[np.isfinite(v)] if v is not None else np.empty(0)
        return (float(v.min()), float(v.max())) if v.size else nan2
    roll, pitch, yaw = on_grid("roll"), on_grid("pitch"), on_grid("yaw")
    tilt = rng(np.degrees(np.maximum(np.abs(roll), np.abs(pitch)))) if roll is not None and pitch is not None else nan2
    vx, vy = on_grid("vx"), on_grid("vy")
    speed = rng(np.hypot(vx, vy)) if vx is not None and vy is not None else nan2
    yaw_span = math.nan
    if yaw is not None and f.has("yaw"):
        s = f["yaw"]
        spans = []
        for a, b in ivs:
            m = (s.t >= a) & (s.t <= b)
            if m.sum() >= 2:
                u = np.unwrap(s.values[m])
                spans.append(float(np.degrees(u.max() - u.min())))
        yaw_span = max(spans) if spans else math.nan
    return tilt, speed, yaw_span


def check_prior_data(flights, prior, targets, ts: float, role: str = "training") -> "Fitness | None":
    """:func:`assess` of ``flights`` for ``prior`` and its ``targets`` (the signals its terms read
    plus each target's velocity): raises :class:`DataError` naming the first problem and how to
    override it, else returns the Fitness (warnings inside). None for priors of vehicles the
    check does not know (e.g. the ground robot's unicycle). Used by identify and diagnose."""
    kind = getattr(prior, "vehicle", "multirotor")
    if kind not in _ACCEPTS:
        return None
    targets = [t for t in targets if t in prior.targets]
    needed = sorted({s for t in targets for s in prior.signals(t)} | {state_of(t) for t in targets})
    fit = assess(list(flights), needed_signals=needed, ts=ts, prior_kind=kind)
    if fit.problems:
        more = f" (and {len(fit.problems) - 1} more problem(s))" if len(fit.problems) > 1 else ""
        raise DataError(f"the {role} data cannot identify the {prior.name} model: {fit.problems[0]}{more}")
    return fit


def usable_signals(flights, ts: float) -> set:
    """The signals every flight has at a rate the data-fitness check accepts for a grid of
    ``ts`` (≥ :data:`MIN_RATE_STEPS` / Ts): ``auto`` chooses among these, so a
    4 Hz ESC telemetry does not win over 100 Hz motor commands."""
    names = None
    for f in flights:
        n = {name for name, sig in getattr(f, "signals", {}).items()
             if len(sig) < 2 or sig.rate_hz >= MIN_RATE_STEPS / ts}
        names = n if names is None else names & n
    return names or set()
