"""Is a set of flights fit for identifying a model? Checked BEFORE any fitting (issues 13, 29).

:func:`assess` looks at each flight's vehicle type (declared, or judged from the data when the
log declares none), airborne time, the rates of the signals the model needs, how many grid
samples remain at the sampling period, and how much the flight excites the model (tilt,
horizontal speed, yaw). It returns a :class:`Fitness` holding the measurements, ``problems``
(refusals, most fundamental first; each one line saying how to override) and ``warnings``
(marginal data). Pure: nothing is printed; :meth:`Fitness.raise_if_refused` raises a
:class:`~droneid.errors.DataError` with the first problem.

:func:`prior_fitness` is the ONE verdict of a prior on a set of flights: identify, diagnose and
``inspect`` call it (predict calls :func:`assess` with the signals of the saved models), so the
same data get the same accept/refuse answer everywhere.

Rates and counts are gap-aware (:func:`coverage`): a signal exists only in its *bursts* (runs
of samples without a gap longer than :data:`GAP_S` or five median steps, the rule the dataset
builder splits at); its rate is the samples per second of existence, not the median step
(MAVLink bursts of 7 ms steps every 0.25 s are 4 Hz, not 143 Hz). The airborne time and the grid
samples are counted over the airborne intervals minus every needed signal's gaps, as the
dataset builder counts them.

Order of the refusals (:data:`REASON_ORDER`): no airborne data (never armed, never off the
ground), then the vehicle, then no valid state estimate, then missing signals, then rates, then
too few samples.

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

Vehicle: a multirotor prior on a log that declares a fixed-wing or a rover is refused; a VTOL is
a warning. A log that declares nothing (mocap CSV, MCAP) is judged from its data
(:func:`vehicle_evidence`): a multirotor can fly slowly and accelerates the way its thrust axis
tilts (a_h = g·tan(tilt)); data that never come below 2 m/s, or tilt regardless of their
acceleration, are refused for a multirotor prior, with the evidence and the
``--vehicle multirotor``. ``vehicle=`` (the user's ``--vehicle``) replaces every flight's
declaration.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from priors.thrust import COMMAND_SOURCES, in_rpm_unit

from droneid.logs.consistency import raise_if_inconsistent
from droneid.core.text import undeclared_line
from droneid.errors import ConfigError, DataError, check_choice
from droneid.logs.flight import MAX_GAP_S, VEHICLE_TYPES, Flight, Signal
from droneid.logs.in_flight import in_flight_intervals, resample_signal
from droneid.core.lazy import lazy_module
from droneid.core.targets import state_of, targets_for
from droneid.core.numerics import rounded
from droneid.logs.vehicle_evidence import (EVIDENCE_STEP_S, HOVER_ACCEL_MS2, HOVER_SPEED_MS, MAX_HOVER_TILT_DEG,
                               MAX_TILT_MISMATCH_DEG, MIN_HOVER_S, NEVER_SLOW_MS, VehicleEvidence, tilt_deg,
                               vehicle_evidence)

#: the prior registry (sympy) and the log readers, loaded when a verdict names a prior or a hint
#: names a reader's option
_registry = lazy_module("priors.registry")
_parsers = lazy_module("parsers")

__all__ = ["assess", "check_prior_data", "prior_fitness", "usable_signals", "too_slow_signals",
           "prior_for_flights", "coverage", "Coverage",
           "Fitness", "FlightFitness", "TILT_DRAG_SIGNALS",
           "ROTOR_THRUST_SIGNALS", "REASON_ORDER", "fitness_by_prior", "INSPECTED_PRIORS", "prior_signals"]

MIN_RATE_STEPS = 0.25
SLOW_DYNAMICS_HZ = 5.0
MIN_AIRBORNE_S = 10.0
MIN_SAMPLES = 50
MIN_TILT_RANGE_DEG = 3.0
MIN_SPEED_RANGE_MS = 1.0
MIN_YAW_SPAN_DEG = 20.0
#: a flight longer than this (2 days) has damaged time stamps: not scanned for airborne time
MAX_SPAN_S = 172_800.0
#: a longer pause between samples (or five median steps, whichever is longer) is a gap
#: (:data:`droneid.logs.flight.MAX_GAP_S`, the dataset builder's default ``max_gap_s``): fitness and
#: identify split at the same places
GAP_S = MAX_GAP_S

#: signals of the tilt-drag prior (vx_dot, vy_dot from tilt and velocity)
TILT_DRAG_SIGNALS = ("vx", "vy", "roll", "pitch", "yaw")
#: signals of a rotor-thrust model of vz_dot (plus one rotor signal: rpm1, motor1 or throttle)
ROTOR_THRUST_SIGNALS = ("vz", "roll", "pitch")

#: the kinds of refusal, most fundamental first (problems are listed in this order)
REASON_ORDER = ("airborne", "vehicle", "state", "missing", "rate", "samples")

#: vehicle types (flight.VEHICLE_TYPES) a prior's vehicle kind (priors.base.VEHICLE_KINDS)
#: accepts without comment / refuses; the kinds not listed (ground, any) are not checked
_ACCEPTS = {"multirotor": ("multirotor",), "fixed-wing": ("fixed-wing",)}
_REFUSES = {"multirotor": ("fixed-wing", "rover"), "fixed-wing": ("multirotor", "rover")}
_STATE = ("x", "y", "z", "vx", "vy", "vz")


# -- gap-aware coverage of one signal -----------------------------------------------------------
@dataclass(frozen=True)
class Coverage:
    """Where a signal has data: ``bursts`` ((start_s, end_s) runs without a gap), the seconds
    they cover (``existence_s``), its ``count`` of samples and ``rate_hz``, the samples per
    second of existence (nan with fewer than two samples in every burst)."""
    count: int
    bursts: tuple[tuple[float, float], ...]
    existence_s: float
    rate_hz: float

    def describe(self, limit: int = 4) -> str:
        """``"5 bursts: 0.0-6.3 s, 41.9-43.4 s, ... (9.3 s of data)"``; ``""`` for one burst."""
        if len(self.bursts) <= 1:
            return ""
        shown = ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in self.bursts[:limit])
        more = f", ... ({len(self.bursts) - limit} more)" if len(self.bursts) > limit else ""
        return f"{len(self.bursts)} bursts: {shown}{more} ({self.existence_s:.1f} s of data)"


def coverage(sig: Signal) -> Coverage:
    """The gap-aware :class:`Coverage` of ``sig`` (its :meth:`~droneid.logs.flight.Signal.bursts` and
    :attr:`~droneid.logs.flight.Signal.rate_hz`)."""
    bursts = sig.bursts()
    return Coverage(len(sig), bursts, float(sum(b - a for a, b in bursts)), sig.rate_hz)


# -- the verdict --------------------------------------------------------------------------------
@dataclass(frozen=True)
class FlightFitness:
    """Measurements of one flight (seconds, Hz, degrees, m/s).

    ``airborne_s`` and ``samples`` count the airborne intervals where every needed signal has
    data (gaps cut out, as the dataset builder cuts them); ``airborne_basis`` says how the
    airborne part was found; ``rates_hz`` are gap-aware (:func:`coverage`), nan when absent;
    ``bursts`` describes signals that come in bursts; ``vehicle`` is the evidence of the data."""
    name: str
    vehicle_type: str
    vehicle_declared: str | None
    airborne_s: float
    airborne_notes: tuple[str, ...]
    rates_hz: Mapping[str, float]
    samples: int
    tilt_deg: tuple[float, float]           # (min, max) tilt from vertical while airborne
    speed_ms: tuple[float, float]           # (min, max) horizontal speed while airborne
    yaw_span_deg: float                     # max - min of the unwrapped yaw while airborne
    airborne_basis: str = ""
    bursts: Mapping[str, str] = field(default_factory=dict)
    vehicle: VehicleEvidence | None = None

    def __post_init__(self):
        object.__setattr__(self, "rates_hz", MappingProxyType(dict(self.rates_hz)))
        object.__setattr__(self, "bursts", MappingProxyType(dict(self.bursts)))


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
        "min_yaw_span_deg": MIN_YAW_SPAN_DEG, "gap_s": GAP_S, "hover_speed_ms": HOVER_SPEED_MS,
        "hover_accel_ms2": HOVER_ACCEL_MS2, "min_hover_s": MIN_HOVER_S,
        "max_hover_tilt_deg": MAX_HOVER_TILT_DEG, "max_tilt_mismatch_deg": MAX_TILT_MISMATCH_DEG,
        "never_slow_ms": NEVER_SLOW_MS}))
    prior: str = ""
    #: (flight, what the data look like, the same in short) of every flight whose log does not
    #: declare its vehicle type; ``warnings`` says it in one line (:func:`undeclared_line`)
    undeclared: tuple = ()

    @property
    def ok(self) -> bool:
        """True when nothing is refused (warnings may remain)."""
        return not self.problems

    def raise_if_refused(self, lead: str = "") -> None:
        """Raise :class:`DataError` naming every problem, if any, in one line (most fundamental
        first, numbered when there are several); ``lead`` goes before them (e.g. "the training
        data cannot identify the X model: ")."""
        if len(self.problems) == 1:
            raise DataError(lead + self.problems[0])
        if self.problems:
            raise DataError(f"{lead}{len(self.problems)} problems: "
                            + "; ".join(f"({i}) {p}" for i, p in enumerate(self.problems, 1)))

    def to_dict(self) -> dict:
        """A JSON-ready dict (non-finite numbers as None)."""
        return {
            "ok": self.ok, "prior": self.prior, "prior_kind": self.prior_kind, "ts": self.ts,
            "needed_signals": list(self.needed_signals),
            "problems": list(self.problems), "warnings": list(self.warnings),
            "thresholds": dict(self.thresholds),
            "flights": [{
                "name": f.name, "vehicle_type": f.vehicle_type, "vehicle_declared": f.vehicle_declared,
                "airborne_s": rounded(f.airborne_s), "airborne_basis": f.airborne_basis,
                "airborne_notes": list(f.airborne_notes),
                "rates_hz": {k: rounded(v) for k, v in f.rates_hz.items()}, "bursts": dict(f.bursts),
                "samples": f.samples,
                "tilt_deg": [rounded(x) for x in f.tilt_deg], "speed_ms": [rounded(x) for x in f.speed_ms],
                "yaw_span_deg": rounded(f.yaw_span_deg),
                "vehicle_evidence": f.vehicle.to_dict() if f.vehicle is not None else None}
                for f in self.flights],
        }


def assess(flights: Flight | Sequence[Flight], *, needed_signals: Sequence[str], ts: float,
           prior_kind: str = "multirotor", vehicle: str | None = None, prior: str = "",
           inputs_fixed: bool = False, optional_signals: Sequence[str] = ()) -> Fitness:
    """Judge whether ``flights`` can identify a ``prior_kind`` model of ``needed_signals`` on a
    grid of ``ts`` seconds (see the module doc for the thresholds and the order of problems).

    ``vehicle`` (one of :data:`droneid.logs.flight.VEHICLE_TYPES`) overrides each flight's declared
    vehicle type, as ``--vehicle`` does; ``prior`` names the prior in the result (display only).
    ``inputs_fixed``: the signals are those of a model already identified (predict), so a missing
    one can only come from the log, not from choosing another prior or target.
    ``optional_signals``: signals a later stage may use (a command prior's battery voltage): their
    rates are in the warnings only, never refused (using them is that stage's decision).
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
    problems: list[tuple[int, str]] = []
    warnings: list[str] = []
    undeclared: list[tuple[str, str]] = []
    out = []
    total_samples = 0

    def refuse(kind, text):
        problems.append((REASON_ORDER.index(kind), text))
    # damaged values (1e308, inf) must not raise numpy warnings: they end up non-finite and
    # are left out by the finiteness checks below
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        for f in flights:
            name = f.name
            vtype = vehicle or f.provenance.vehicle_type
            declared = (f"--vehicle {vehicle}" if vehicle else f.provenance.vehicle_declared)
            covs = {s: coverage(f[s]) for s in needed if f.has(s)}
            rates = {s: (covs[s].rate_hz if s in covs else math.nan) for s in needed}
            bursts = {s: c.describe() for s, c in covs.items() if len(c.bursts) > 1}
            raw, notes, basis = _airborne(f, ts)
            ivs = _with_data(raw, covs.values())
            airborne = float(sum(b - a for a, b in ivs))
            samples = _grid_samples(ivs, ts)
            total_samples += samples
            evidence = vehicle_evidence(f, ivs or raw)
            _vehicle_verdict(name, vtype, declared, prior_kind, evidence, refuse, warnings, undeclared)
            missing = [s for s in needed if not f.has(s)]
            invalid = _invalid_state(f, missing)
            if invalid:
                refuse("state", f"{name}: no valid state estimate ({invalid}): the log's "
                                f"{', '.join(s for s in missing if s in _STATE)} are never valid; "
                                f"use a log with a position/velocity fix")
            for s in missing:
                if invalid and s in _STATE:
                    continue
                refuse("missing", f"{name}: signal '{s}' is missing{_map_hint(f, s, inputs_fixed)}")
            if not raw:
                refuse("airborne", f"{name}: no airborne data ({'; '.join(notes) or 'no in-flight interval'}): "
                                   f"models are fitted and scored on the airborne part of a log only; use a "
                                   f"log in which the vehicle flies (droneid inspect shows its armed and "
                                   f"in-flight intervals)")
            elif not ivs and not missing:
                refuse("airborne", f"{name}: no airborne data where every needed signal has samples "
                                   f"({', '.join(needed)}): airborne {_fmt_ivs(raw)}")
            elif 0 < airborne < MIN_AIRBORNE_S:
                warnings.append(f"{name}: only {airborne:.1f} s airborne (< {MIN_AIRBORNE_S:.0f} s; "
                                f"{basis}): expect loose estimates")
            in_air = {s: b for s, b in bursts.items() if _gap_in(covs[s].bursts, raw)}
            for text in dict.fromkeys(in_air.values()):     # gaps while airborne only
                names = ", ".join(s for s, b in in_air.items() if b == text)
                warnings.append(f"{name}: {names} {'come' if ',' in names else 'comes'} in {text}: "
                                f"rates and samples count the time with data only")
            optional = {s: coverage(f[s]).rate_hz for s in optional_signals if s not in needed and f.has(s)}
            _rate_verdict(name, rates, ts, refuse, warnings, optional)
            tilt, speed = _excitation(f, ivs)
            yaw_span = evidence.yaw_span_deg
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
                                     tilt, speed, yaw_span, basis, bursts, evidence))
    if 0 < total_samples < MIN_SAMPLES:
        refuse("samples", f"only {total_samples} samples in flight at Ts = {ts:g} s "
                          f"(< {MIN_SAMPLES}): use more or longer flights")
    ordered = tuple(text for _, text in sorted(problems, key=lambda p: p[0]))
    warnings = [undeclared_line(undeclared) if w == _UNDECLARED else w for w in warnings]
    return Fitness(tuple(out), needed, float(ts), prior_kind, ordered, tuple(warnings), prior=prior,
                   undeclared=tuple(undeclared))


def _gap_in(bursts, ivs) -> bool:
    """Whether a gap between ``bursts`` overlaps one of the intervals ``ivs`` (s)."""
    gaps = [(a[1], b[0]) for a, b in zip(bursts, bursts[1:])]
    return any(g0 < b and a < g1 for g0, g1 in gaps for a, b in ivs)


def _fmt_ivs(ivs) -> str:
    return ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in ivs) or "none"


def _with_data(ivs, covs) -> list:
    """``ivs`` cut to where every coverage has a burst (the builder's spans-minus-gaps rule)."""
    out = list(ivs)
    for c in covs:
        nxt = []
        for a, b in out:
            for c0, c1 in c.bursts:
                lo, hi = max(a, c0), min(b, c1)
                if hi > lo:
                    nxt.append((lo, hi))
        out = nxt
    return sorted(out)


def _grid_samples(ivs, ts: float) -> int:
    """Grid points at ``ts`` a forward-difference dataset keeps in ``ivs``: ``floor(len/ts) + 1``
    per interval less the last one (no forward difference), intervals of < 3 points skipped."""
    n = 0
    for a, b in ivs:
        k = int(math.floor((b - a) / ts + 1e-9)) + 1
        if k >= 3:
            n += k - 1
    return n


def _invalid_state(f: Flight, missing) -> str:
    """The reader's count of state samples flagged invalid, when state signals are missing."""
    if not any(s in _STATE for s in missing):
        return ""
    bad = [f"{k}: {n}" for k, n in f.diagnostics.skipped.items() if "valid" in k.lower()]
    return "; ".join(bad)


def _map_hint(f: Flight, signal: str, inputs_fixed: bool = False) -> str:
    """The fixes for a missing ``signal`` that exist: name the field holding it in the terms of
    the log's format (``--topic`` for MCAP, ``--column`` for CSV; none for formats whose fields
    are fixed, ULog, DataFlash), then a model that does not read it (``--prior`` / ``--target``
    of identify, diagnose, inspect) or, when the model is given (``inputs_fixed``: predict), a log
    that has it."""
    try:
        options = _parsers.READERS[f.provenance.format].options
    except (ImportError, KeyError):
        options = ()
    other = ("use a log that has it (the model reads it)" if inputs_fixed else
             "choose a prior or target that does not read it (identify / diagnose --prior, --target)")
    if "topics" in options:
        return f": map a topic to it (--topic {signal}=TOPIC) or {other}"
    if "column_map" in options:
        return f": map a column to it (--column {signal}=COLUMN) or {other}"
    return f": the {f.provenance.format} log has no field for it; {other}"


def _rate_verdict(name, rates, ts, refuse, warnings, optional=None) -> None:
    """One line per kind of rate trouble, listing the signals (slowest first); ``optional``
    ({signal: Hz}) in the coarse line only (never refused; a voltage is no dynamics)."""
    known = sorted(((hz, s) for s, hz in rates.items() if math.isfinite(hz)))
    extra = sorted(((hz, s) for s, hz in (optional or {}).items() if math.isfinite(hz)))
    refused = [(hz, s) for hz, s in known if hz * ts < MIN_RATE_STEPS]
    coarse = sorted([x for x in known if MIN_RATE_STEPS <= x[0] * ts < 0.95] + [x for x in extra if x[0] * ts < 0.95])
    slow = [x for x in known if x[0] < SLOW_DYNAMICS_HZ and x[0] * ts >= MIN_RATE_STEPS]  # coarse: 5 % jitter

    def listing(items):
        return ", ".join(f"{s} {hz:.1f} Hz" for hz, s in items)
    if refused:
        hz, s = refused[0]
        refuse("rate",
               f"{name}: {s} is logged at {hz:.1f} Hz, below 1/(4 Ts) = {MIN_RATE_STEPS / ts:.0f} Hz "
               f"for Ts = {ts:g} s (2/Ts = {2 / ts:.0f} Hz is ideal): use --ts "
               f"{_nice(MIN_RATE_STEPS / hz)} or more, or a log with faster {s}"
               + (f" (also slow: {listing(refused[1:])})" if len(refused) > 1 else ""))
    if coarse:
        warnings.append(f"{name}: logged slower than the grid (1/Ts = {1 / ts:.0f} Hz), grid values "
                        f"between samples are interpolated: {listing(coarse)}")
    if slow:
        warnings.append(f"{name}: below {SLOW_DYNAMICS_HZ:.0f} Hz, multirotor dynamics are barely resolved: {listing(slow)}")


def _nice(x: float) -> str:
    for step in (0.05, 0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0):
        if x <= step:
            return f"{step:g}"
    return f"{x:.0f}"


#: what droneid offers a vehicle its multirotor priors do not describe (the plain answer first)
_OTHER_VEHICLE = {
    "fixed-wing": "droneid has no built-in fixed-wing model (its built-in priors tilt-drag and "
                  "rotor-thrust describe multirotors); a fixed-wing needs your own prior "
                  "(--prior FILE.toml:NAME with vehicle = \"fixed-wing\", docs/priors.md)",
    "rover": "droneid's ground-vehicle model is the unicycle prior (--prior unicycle)",
}


#: where the one line about undeclared vehicle types goes among the warnings
_UNDECLARED = "\0undeclared"


def _vehicle_verdict(name, vtype, declared, prior_kind, evidence, refuse, warnings, undeclared) -> None:
    said = f" ({declared})" if declared else ""
    what = {"multirotor": "multirotor (quadrotor)"}.get(prior_kind, prior_kind)
    if vtype in _REFUSES.get(prior_kind, ()):
        other = f"{_OTHER_VEHICLE[vtype]}; " if prior_kind == "multirotor" and vtype in _OTHER_VEHICLE else ""
        refuse("vehicle", f"{name}: {what} prior on a {vtype} log{said}: {other}pass --vehicle "
                          f"{prior_kind} to override")
    elif vtype == "unknown" and prior_kind == "multirotor" and evidence.looks == "not a multirotor":
        seen = [f"tilt up to {evidence.tilt_max_deg:.0f} deg"] if math.isfinite(evidence.tilt_max_deg) else []
        seen += [f"yaw turns {evidence.yaw_span_deg:.0f} deg"] if math.isfinite(evidence.yaw_span_deg) else []
        refuse("vehicle", f"{name}: the log does not declare its vehicle and the data do not look like a "
                          f"multirotor: {'; '.join(evidence.reasons + tuple(seen))}: "
                          f"{_OTHER_VEHICLE['fixed-wing']}; if it is a multirotor after all, pass "
                          f"--vehicle multirotor")
    elif vtype == "unknown":
        judged = (f"the data look like a multirotor ({evidence.text()})" if evidence.looks == "multirotor"
                  else f"a {what} is assumed ({'; '.join(evidence.reasons) or 'undecided'})")
        undeclared.append((name, judged, "the data look like a multirotor" if evidence.looks == "multirotor"
                           else f"a {what} is assumed"))
        if len(undeclared) == 1:
            warnings.append(_UNDECLARED)    # the merged line goes here (undeclared_line)
    elif vtype not in _ACCEPTS.get(prior_kind, ()):
        warnings.append(f"{name}: {what} prior on a {vtype} log{said}: only its "
                        f"{'hover' if vtype == 'vtol' else 'matching'} phases follow the prior")


def _airborne(f: Flight, ts: float):
    """(intervals, notes, basis): the airborne, pre-crash intervals and how they were found."""
    if f.duration_s > MAX_SPAN_S:
        return [], [f"a time span of {f.duration_s:.3g} s is not a flight (damaged time stamps?)"], ""
    if "armed" in f.segments and not f.segments["armed"]:
        return [], ["never armed (the log's armed state is false throughout)"], ""
    ivs, notes = in_flight_intervals(f, ts=ts)
    seg = f.segments
    basis = ("from the log's in-flight state" if seg.get("in_flight") else
             "from the log's armed state" if seg.get("armed") else
             "the log has no armed or in-flight state: all of it counts as airborne unless ground is detected")
    return [(a, b) for a, b in ivs if b > a], list(notes), basis


def _excitation(f: Flight, ivs):
    """((min, max) tilt from vertical in deg, (min, max) horizontal speed in m/s) on a 0.1 s
    grid inside ``ivs``."""
    nan2 = (math.nan, math.nan)
    step = EVIDENCE_STEP_S
    t = np.concatenate([np.arange(a, b, step) for a, b in ivs if b - a >= step] or [np.empty(0)])
    if t.size == 0:
        return nan2, nan2

    def on_grid(name):
        return resample_signal(f[name], t) if f.has(name) else None

    def rng(v):
        v = v[np.isfinite(v)] if v is not None else np.empty(0)
        return (float(v.min()), float(v.max())) if v.size else nan2
    roll, pitch = on_grid("roll"), on_grid("pitch")
    tilt = rng(tilt_deg(roll, pitch)) if roll is not None and pitch is not None else nan2
    vx, vy = on_grid("vx"), on_grid("vy")
    with np.errstate(over="ignore", invalid="ignore"):
        speed = rng(np.hypot(vx, vy)) if vx is not None and vy is not None else nan2
    return tilt, speed


# -- one verdict per prior ------------------------------------------------------------------------
def prior_signals(prior, targets) -> tuple[str, ...]:
    """The signals a ``prior``'s models of ``targets`` read: their inputs, the signals of their
    terms and each target's state (what the dataset builder will need)."""
    targets = [t for t in targets if t in prior.targets]
    return tuple(sorted({s for t in targets for s in (*prior.signals(t), *prior.inputs(t))}
                        | {state_of(t) for t in targets}))


def prior_fitness(flights, prior, targets, ts: float, vehicle: str | None = None) -> "Fitness | None":
    """THE fitness verdict of ``flights`` for ``prior`` and its ``targets`` (never raises on a
    refusal: see :func:`check_prior_data`); None for priors of vehicles the check does not know
    (the unicycle). identify, diagnose and ``inspect`` use this."""
    kind = getattr(prior, "vehicle", "multirotor")
    if kind not in _ACCEPTS:
        return None
    optional = ("battery_voltage",) if getattr(prior, "params", {}).get("source") in COMMAND_SOURCES else ()
    return assess(list(flights), needed_signals=prior_signals(prior, targets), ts=ts, prior_kind=kind,
                  vehicle=vehicle, prior=getattr(prior, "name", ""), optional_signals=optional)


def check_prior_data(flights, prior, targets, ts: float, role: str = "training") -> "Fitness | None":
    """:func:`prior_fitness`, raising :class:`DataError` naming the first problem and how to
    override it; else returns the Fitness (warnings inside). Used by identify and diagnose.

    First of all, the flights' redundant signals must agree (:mod:`droneid.logs.consistency`): a log
    read in the wrong convention raises :class:`~droneid.logs.consistency.ConventionError`, one line
    per mistake with its fix, before any other verdict."""
    raise_if_inconsistent(flights, role)
    fit = prior_fitness(flights, prior, targets, ts)
    if fit is not None:
        fit.raise_if_refused(f"the {role} data cannot identify the {prior.name} model: ")
    return fit


def usable_signals(flights, ts: float) -> set:
    """The signals every flight has at a rate the data-fitness check accepts for a grid of
    ``ts`` (gap-aware rate ≥ :data:`MIN_RATE_STEPS` / Ts): ``auto`` chooses among these, so a
    4 Hz ESC telemetry does not win over 100 Hz motor commands."""
    names = None
    for f in flights:
        n = set()
        for name, sig in getattr(f, "signals", {}).items():
            hz = sig.rate_hz
            if not math.isfinite(hz) or hz >= MIN_RATE_STEPS / ts:
                n.add(name)
        names = n if names is None else names & n
    return names or set()


def too_slow_signals(flights, ts: float) -> dict:
    """{signal: its slowest gap-aware rate (Hz) over the flights} of the signals every flight
    has but not every flight logs fast enough for a grid of ``ts`` (the ones
    :func:`usable_signals` leaves out), so a choice can say why it passed them over."""
    flights = list(flights)
    if not flights:
        return {}
    every = set.intersection(*(set(getattr(f, "signals", {})) for f in flights))
    out = {}
    for name in every - usable_signals(flights, ts):
        rates = [f.signals[name].rate_hz for f in flights]
        out[name] = min((r for r in rates if math.isfinite(r)), default=math.nan)
    return out


def prior_for_flights(spec, flights, ts: float):
    """(PriorModel, why): ``--prior`` (a name, ``auto``, ``FILE.toml:NAME`` or a PriorModel)
    resolved on these flights, choosing among the signals they log fast enough for a grid of
    ``ts`` (:func:`usable_signals`); a thrust source logged too slowly is named in ``why``. The
    one choice identify, diagnose and ``inspect`` make."""
    prior, why = _registry.prior_for(spec, usable_signals(flights, ts), slow=too_slow_signals(flights, ts))
    return in_rpm_unit(prior, {f["rpm1"].unit for f in flights if f.has("rpm1")}), why


#: the built-in priors :func:`fitness_by_prior` judges by default (what ``droneid inspect`` shows)
INSPECTED_PRIORS = ("tilt-drag", "rotor-thrust")


def fitness_by_prior(flights, ts: float, priors: Sequence[str] = INSPECTED_PRIORS) -> dict:
    """{prior name: :meth:`Fitness.to_dict` plus ``applies`` and ``prior_reason``} for each of
    ``priors``, resolved and judged exactly as identify does (:func:`priors.registry.prior_for` on
    the :func:`usable_signals`, then :func:`prior_fitness` of every target the prior models), and
    ``"auto"``: the prior ``--prior auto`` would choose and why. A prior whose signals exist only
    too slowly is judged on them (the rate refusal says so) rather than called inapplicable."""
    flights = list(flights)
    usable, slow = usable_signals(flights, ts), too_slow_signals(flights, ts)
    every = set.intersection(*(set(f.names) for f in flights)) if flights else set()
    out = {}
    for spec in priors:
        try:
            prior, why = _registry.prior_for(spec, usable, slow=slow)
        except ConfigError as exc:
            try:
                prior, why = _registry.prior_for(spec, every)
            except ConfigError:
                out[spec] = {"ok": False, "applies": False, "ts": ts, "problems": [str(exc)],
                             "warnings": [], "flights": []}
                continue
        fit = prior_fitness(flights, prior, targets_for(prior), ts)
        out[spec] = (dict(fit.to_dict(), applies=True, prior_reason=why) if fit is not None else
                     {"ok": True, "applies": True, "ts": ts, "problems": [], "warnings": [], "flights": [],
                      "prior_reason": why})
    auto, why = _registry.prior_for("auto", usable, slow=slow)
    out["auto"] = {"prior": auto.name, "reason": why}
    return out
