"""The ``Flight``: the one container every reader returns and every later stage consumes.

A flight is a set of named signals, each with its own time stamps (logs mix rates), in the ONE
internal convention of :mod:`droneid.core.frames`: float64 seconds from the log start, SI units,
ENU world frame, FLU body frame, Z-Y-X Euler angles. :data:`CANONICAL_SIGNALS` names the signals
users type on the command line.
"""
from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import PurePath
from types import MappingProxyType

import numpy as np

from droneid.errors import DataError, MissingSignalError

__all__ = [
    "CANONICAL_SIGNALS", "ROTOR_SIGNALS", "VEHICLE_TYPES", "MAX_GAP_S", "TIME_UNITS", "MAV_TYPES", "VEHICLE_PARAMETERS", "vehicle_from_mav_type", "Signal", "Provenance", "Diagnostics", "Event", "Flight",
    "canonical_unit", "is_canonical", "fingerprint", "distinct_flights",
]

#: Canonical signal names -> (unit, meaning). Per-motor signals (``motor1`` .. ``motor16``,
#: ``rpm1`` .. ``rpm16``) are in :data:`ROTOR_SIGNALS`; see docs/signals.md.
CANONICAL_SIGNALS: Mapping[str, tuple[str, str]] = MappingProxyType({
    "x": ("m", "position east of the local origin (world ENU)"),
    "y": ("m", "position north of the local origin (world ENU)"),
    "z": ("m", "height above the local origin (world ENU, up)"),
    "vx": ("m/s", "velocity east (world ENU)"),
    "vy": ("m/s", "velocity north (world ENU)"),
    "vz": ("m/s", "velocity up (world ENU)"),
    "roll": ("rad", "Z-Y-X Euler roll of the FLU body in ENU (positive: right side down)"),
    "pitch": ("rad", "Z-Y-X Euler pitch of the FLU body in ENU (positive: nose down)"),
    "yaw": ("rad", "Z-Y-X Euler yaw, counter-clockwise from east, wrapped to [-pi, pi)"),
    "qw": ("1", "attitude quaternion, scalar part (Hamilton, FLU body to ENU world)"),
    "qx": ("1", "attitude quaternion, x part"),
    "qy": ("1", "attitude quaternion, y part"),
    "qz": ("1", "attitude quaternion, z part"),
    "wx": ("rad/s", "body angular rate about body x (forward), FLU"),
    "wy": ("rad/s", "body angular rate about body y (left), FLU"),
    "wz": ("rad/s", "body angular rate about body z (up), FLU"),
    "ax": ("m/s^2", "specific force along body x (accelerometer, FLU)"),
    "ay": ("m/s^2", "specific force along body y (accelerometer, FLU)"),
    "az": ("m/s^2", "specific force along body z (accelerometer, FLU; +9.81 at rest)"),
    "throttle": ("1", "collective throttle command, 0..1"),
    "thrust": ("N", "collective thrust along body z"),
    "battery_voltage": ("V", "battery voltage"),
    "battery_current": ("A", "battery current"),
    "lat": ("deg", "GNSS latitude (WGS84 degrees; the one non-SI canonical unit)"),
    "lon": ("deg", "GNSS longitude (WGS84 degrees)"),
    "alt": ("m", "altitude above mean sea level"),
    "baro_alt": ("m", "barometric altitude relative to the log's baro reference"),
})

_MOTOR_RE = re.compile(r"^motor([1-9]|1[0-6])$")
_RPM_RE = re.compile(r"^rpm([1-9]|1[0-6])$")

#: Per-motor signal families, N = 1..16 in the vehicle's motor order (ArduPilot / PX4 motor
#: numbering): prefix -> (regex, unit, meaning).
ROTOR_SIGNALS: Mapping[str, tuple[re.Pattern, str, str]] = MappingProxyType({
    "motor": (_MOTOR_RE, "1", "motor N command, normalised to 0..1 (source says from which range)"),
    "rpm": (_RPM_RE, "rpm", "motor N speed in revolutions per minute; a reader that gets "
                            "electrical rpm (ESC eRPM = rpm x motor pole pairs) gives the unit "
                            "'erpm' and says so in the source (the pole-pair factor is left to "
                            "the fitted scale unless the log states it)"),
})


#: vehicle parameters a reader keeps in :attr:`Provenance.parameters` (ArduPilot's names): the
#: thrust curve (MOT_THST_EXPO, MOT_THST_HOVER; THR_MID, the hover throttle before ArduCopter 3.5),
#: the command normalisation (MOT_PWM_MIN/MAX, MOT_SPIN_ARM/MIN/MAX) and the voltage scaling
#: (MOT_BAT_VOLT_MAX/MIN; MOT_THST_BAT_MAX/MIN before ArduCopter 3.6)
VEHICLE_PARAMETERS = ("MOT_THST_EXPO", "MOT_THST_HOVER", "MOT_SPIN_ARM", "MOT_SPIN_MIN", "MOT_SPIN_MAX",
                      "MOT_PWM_MIN", "MOT_PWM_MAX", "MOT_BAT_VOLT_MAX", "MOT_BAT_VOLT_MIN",
                      "MOT_THST_BAT_MAX", "MOT_THST_BAT_MIN", "THR_MID")
#: time units a log's stamps may be in (``--time-unit``) -> seconds per unit; droneid's is "s"
TIME_UNITS: Mapping[str, float] = MappingProxyType({"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9})

#: a pause between samples longer than this (or five median steps, whichever is longer) is a
#: gap: :meth:`Signal.gaps`, and the dataset builder's default ``max_gap_s``
MAX_GAP_S = 0.5


def _rotor(name: str):
    for prefix, (rx, unit, _) in ROTOR_SIGNALS.items():
        m = rx.match(name)
        if m:
            return prefix, int(m.group(1)), unit
    return None


def is_canonical(name: str) -> bool:
    """True for a canonical signal name (including ``motor1..16`` and ``rpm1..16``)."""
    return name in CANONICAL_SIGNALS or _rotor(name) is not None


def canonical_unit(name: str) -> str:
    """The unit of a canonical signal (``"1"`` for dimensionless)."""
    r = _rotor(name)
    if r:
        return r[2]
    try:
        return CANONICAL_SIGNALS[name][0]
    except KeyError:
        raise MissingSignalError(name, list(CANONICAL_SIGNALS) + ["motor1", "rpm1"],
                                 where="the canonical signal list") from None


def _through_constructor(obj) -> tuple:
    """``__reduce__`` of a frozen dataclass whose ``__post_init__`` checks its fields and wraps
    mappings in read-only proxies (which cannot be pickled): the class and every field as a
    constructor argument, proxies as plain dicts."""
    return type(obj), tuple(dict(v) if isinstance(v, MappingProxyType) else v
                            for v in (getattr(obj, f.name) for f in fields(obj)))


@dataclass(frozen=True)
class Signal:
    """One time series: ``values[i]`` was valid at ``t[i]`` seconds from the log start.

    ``t`` is strictly increasing float64 seconds; ``values`` is float64 of the same length;
    ``unit`` is an SI unit string; ``source`` names the message/topic and field it came from.
    """
    name: str
    t: np.ndarray
    values: np.ndarray
    unit: str
    source: str = ""

    def __post_init__(self):
        t = np.asarray(self.t, dtype=np.float64)
        v = np.asarray(self.values, dtype=np.float64)
        if t.ndim != 1 or v.shape != t.shape:
            raise DataError(
                f"signal '{self.name}': t and values must be 1-D of equal length, "
                f"got {t.shape} and {v.shape}")
        if t.size > 1 and not np.all(np.diff(t) > 0):
            raise DataError(f"signal '{self.name}': time stamps must be strictly increasing")
        t.setflags(write=False)
        v.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "values", v)

    def __len__(self) -> int:
        return int(self.t.size)

    def __reduce__(self):
        # pickled through the constructor: the copy is checked again and its arrays read-only
        return _through_constructor(self)

    @property
    def rate_hz(self) -> float:
        """Sample rate (Hz) over the time the signal has data: samples per second of its
        :meth:`bursts` (gaps left out), so bursts of 7 ms steps every 0.25 s are 4 Hz, not 143 Hz
        (a median step would say 143); nan without two samples in one burst."""
        bursts = self.bursts()
        span = float(sum(b - a for a, b in bursts))
        n = self.t.size - len(bursts)
        return n / span if span > 0 and n > 0 else math.nan

    def gaps(self, max_gap_s: float = MAX_GAP_S) -> list[tuple[float, float]]:
        """The time intervals (s) with no sample for longer than ``max_gap_s`` or five median
        sample steps, whichever is longer (the dataset builder splits its data there)."""
        if self.t.size < 2:
            return []
        dt = np.diff(self.t)
        limit = max(max_gap_s, 5 * float(np.median(dt)))
        return [(float(self.t[i]), float(self.t[i + 1])) for i in np.flatnonzero(dt > limit)]

    def bursts(self, max_gap_s: float = MAX_GAP_S) -> tuple[tuple[float, float], ...]:
        """The (start_s, end_s) runs of samples between the :meth:`gaps` (one run without gaps;
        none for an empty signal)."""
        if self.t.size == 0:
            return ()
        edges = [float(self.t[0])]
        for a, b in self.gaps(max_gap_s):
            edges += [a, b]
        edges.append(float(self.t[-1]))
        return tuple((edges[i], edges[i + 1]) for i in range(0, len(edges), 2))

    @property
    def start_s(self) -> float:
        return float(self.t[0]) if self.t.size else math.nan

    @property
    def end_s(self) -> float:
        return float(self.t[-1]) if self.t.size else math.nan

    def between(self, t0: float, t1: float) -> "Signal":
        """The samples with ``t0 <= t <= t1`` (seconds)."""
        m = (self.t >= t0) & (self.t <= t1)
        return replace(self, t=self.t[m], values=self.values[m])

    def shifted(self, dt_s: float) -> "Signal":
        """The same signal with every time stamp moved by ``dt_s`` seconds."""
        return replace(self, t=self.t + dt_s)

    @classmethod
    def clean(cls, name: str, t, values, unit: str, source: str = "") -> tuple["Signal", dict]:
        """Build a signal from raw samples, dropping non-finite values and non-increasing stamps.

        Returns the signal and a dict ``{reason: count}`` of what was dropped (empty if nothing).
        A lone stamp later than the next one (while the one before is earlier) is dropped first;
        then duplicate stamps keep the first sample and a stamp earlier than the last kept one is
        dropped.
        """
        t = np.asarray(t, dtype=np.float64).ravel()
        v = np.asarray(values, dtype=np.float64).ravel()
        dropped: dict[str, int] = {}
        finite = np.isfinite(t) & np.isfinite(v)
        if not finite.all():
            dropped["non-finite values"] = int((~finite).sum())
            t, v = t[finite], v[finite]
        if t.size > 2:
            # a lone stamp ahead of its successor while its predecessor is not (a damaged stamp,
            # e.g. one flipped bit) would make every later sample look "backwards": drop it alone
            spike = np.zeros(t.size, dtype=bool)
            spike[1:-1] = (t[1:-1] > t[2:]) & (t[:-2] < t[2:])
            spike[0] = t[0] > t[1] and t[0] > t[2] and t[1] < t[2]
            if spike.any():
                dropped["out-of-sequence time stamps"] = int(spike.sum())
                t, v = t[~spike], v[~spike]
        if t.size > 1:
            keep = np.empty(t.size, dtype=bool)
            keep[0] = True
            running = np.maximum.accumulate(t)
            keep[1:] = t[1:] > running[:-1]
            n_bad = int((~keep).sum())
            if n_bad:
                dup = int((t[1:] == running[:-1]).sum())
                if dup:
                    dropped["duplicate time stamps"] = dup
                if n_bad - dup:
                    dropped["backwards time stamps"] = n_bad - dup
                t, v = t[keep], v[keep]
        return cls(name, t, v, unit, source), dropped


#: The vehicle types a flight can declare (:attr:`Provenance.vehicle_type`).
VEHICLE_TYPES = ("multirotor", "fixed-wing", "vtol", "rover", "unknown")

#: MAVLink MAV_TYPE -> (vehicle type, MAV_TYPE name); types not listed are "unknown".
MAV_TYPES: Mapping[int, tuple[str, str]] = MappingProxyType({
    1: ("fixed-wing", "MAV_TYPE_FIXED_WING"), 2: ("multirotor", "MAV_TYPE_QUADROTOR"),
    3: ("multirotor", "MAV_TYPE_COAXIAL"), 4: ("unknown", "MAV_TYPE_HELICOPTER"),
    10: ("rover", "MAV_TYPE_GROUND_ROVER"), 11: ("rover", "MAV_TYPE_SURFACE_BOAT"),
    12: ("unknown", "MAV_TYPE_SUBMARINE"), 13: ("multirotor", "MAV_TYPE_HEXAROTOR"),
    14: ("multirotor", "MAV_TYPE_OCTOROTOR"), 15: ("multirotor", "MAV_TYPE_TRICOPTER"),
    16: ("fixed-wing", "MAV_TYPE_FLAPPING_WING"), 19: ("vtol", "MAV_TYPE_VTOL_TAILSITTER_DUOROTOR"),
    20: ("vtol", "MAV_TYPE_VTOL_TAILSITTER_QUADROTOR"), 21: ("vtol", "MAV_TYPE_VTOL_TILTROTOR"),
    22: ("vtol", "MAV_TYPE_VTOL_FIXEDROTOR"), 23: ("vtol", "MAV_TYPE_VTOL_TAILSITTER"),
    24: ("vtol", "MAV_TYPE_VTOL_TILTWING"), 25: ("vtol", "MAV_TYPE_VTOL_RESERVED5"),
    29: ("multirotor", "MAV_TYPE_DODECAROTOR"), 35: ("multirotor", "MAV_TYPE_DECAROTOR"),
})


def vehicle_from_mav_type(mav_type: int) -> tuple[str, str]:
    """(vehicle type, declaration text) of a MAVLink MAV_TYPE number."""
    kind, name = MAV_TYPES.get(int(mav_type), ("unknown", f"MAV_TYPE {int(mav_type)}"))
    return kind, name


@dataclass(frozen=True)
class Provenance:
    """Where a flight came from: files, format, vehicle and firmware when known, and notes
    on how signals were obtained (e.g. "vx, vy, vz derived from x, y, z by central differences").

    ``vehicle`` is free text (frame, board); ``vehicle_type`` is one of :data:`VEHICLE_TYPES`,
    from the log's own declaration (MAVLink HEARTBEAT type, ArduPilot firmware name, PX4
    vehicle_status) or the user's ``--vehicle``; ``vehicle_declared`` says which (raw text).
    ``signal_sources``: ``(name, unit, source)`` of each signal as the reader made it (the raw
    field, its unit and the normalisation applied), so a result records what its inputs were.
    ``parameters``: ``(name, value)`` of the vehicle parameters the log declares that droneid
    reads (:data:`VEHICLE_PARAMETERS`: ArduPilot's thrust curve and command normalisation from
    DataFlash PARM), sorted by name."""
    files: tuple[str, ...] = ()
    format: str = "unknown"
    vehicle: str | None = None
    firmware: str | None = None
    notes: tuple[str, ...] = ()
    vehicle_type: str = "unknown"
    vehicle_declared: str | None = None
    signal_sources: tuple[tuple[str, str, str], ...] = ()
    parameters: tuple[tuple[str, float], ...] = ()

    def with_note(self, note: str) -> "Provenance":
        return replace(self, notes=self.notes + (note,))


@dataclass(frozen=True)
class Diagnostics:
    """What went wrong while reading, kept as data: ``skipped`` maps a reason to a count of
    records or samples skipped; ``warnings`` are human-readable lines (gaps, clock problems)."""
    skipped: Mapping[str, int] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "skipped", MappingProxyType(dict(self.skipped)))

    def __reduce__(self):   # a mapping proxy cannot be pickled: through the constructor
        return _through_constructor(self)

    @property
    def total_skipped(self) -> int:
        return int(sum(self.skipped.values()))

    def add(self, skipped: Mapping[str, int] | None = None, warnings: Iterable[str] = ()) -> "Diagnostics":
        """A new Diagnostics with counts added and warnings appended."""
        counts = dict(self.skipped)
        for k, n in (skipped or {}).items():
            if n:
                counts[k] = counts.get(k, 0) + int(n)
        return Diagnostics(counts, self.warnings + tuple(warnings))

    def to_dict(self) -> dict:
        return {"skipped": dict(self.skipped), "total_skipped": self.total_skipped,
                "warnings": list(self.warnings)}


@dataclass(frozen=True)
class Event:
    """A discrete event at ``t_s`` seconds: ``kind`` is e.g. "mode", "armed", "disarmed",
    "takeoff", "land", "crash"; ``text`` says more (mode name, message)."""
    t_s: float
    kind: str
    text: str = ""


@dataclass(frozen=True)
class Flight:
    """A flight log in droneid's internal convention.

    Attributes
    ----------
    signals : mapping name -> :class:`Signal` (canonical names where the quantity is canonical;
        other names are kept for inspection but later stages only ask for canonical ones)
    provenance : :class:`Provenance`
    diagnostics : :class:`Diagnostics`
    segments : mapping of a label ("armed", "in_flight") to tuple of ``(start_s, end_s)``
    events : tuple of :class:`Event`
    """
    signals: Mapping[str, Signal]
    provenance: Provenance = field(default_factory=Provenance)
    diagnostics: Diagnostics = field(default_factory=Diagnostics)
    segments: Mapping[str, tuple[tuple[float, float], ...]] = field(default_factory=dict)
    events: tuple[Event, ...] = ()

    def __post_init__(self):
        sig = dict(self.signals)
        for k, s in sig.items():
            if k != s.name:
                raise DataError(f"signal stored under '{k}' is named '{s.name}'")
        object.__setattr__(self, "signals", MappingProxyType(sig))
        seg = {k: tuple((float(a), float(b)) for a, b in v) for k, v in dict(self.segments).items()}
        object.__setattr__(self, "segments", MappingProxyType(seg))
        object.__setattr__(self, "events", tuple(sorted(self.events, key=lambda e: e.t_s)))

    def __reduce__(self):   # mapping proxies cannot be pickled: through the constructor
        return _through_constructor(self)

    # -- access ---------------------------------------------------------------------------
    def __getitem__(self, name: str) -> Signal:
        try:
            return self.signals[name]
        except KeyError:
            where = self.provenance.files[0] if self.provenance.files else "this flight"
            raise MissingSignalError(name, self.signals, where=where) from None

    def __contains__(self, name: str) -> bool:
        return name in self.signals

    def has(self, *names: str) -> bool:
        """True when every name is a signal of this flight with at least one sample."""
        return all(n in self.signals and len(self.signals[n]) > 0 for n in names)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.signals)

    @property
    def start_s(self) -> float:
        starts = [s.start_s for s in self.signals.values() if len(s)]
        return float(min(starts)) if starts else math.nan

    @property
    def end_s(self) -> float:
        ends = [s.end_s for s in self.signals.values() if len(s)]
        return float(max(ends)) if ends else math.nan

    @property
    def duration_s(self) -> float:
        """Seconds from the first to the last sample of any signal (0 for an empty flight)."""
        if not self.signals:
            return 0.0
        return self.end_s - self.start_s

    @property
    def name(self) -> str:
        """A short label: the first file's stem, or the format."""
        if self.provenance.files:
            return PurePath(self.provenance.files[0]).stem
        return self.provenance.format

    # -- derivation -----------------------------------------------------------------------
    def with_signals(self, *signals: Signal, note: str | None = None) -> "Flight":
        """A new flight with these signals added or replaced (and a provenance note)."""
        sig = dict(self.signals)
        for s in signals:
            sig[s.name] = s
        prov = self.provenance.with_note(note) if note else self.provenance
        return replace(self, signals=sig, provenance=prov)

    def without(self, *names: str) -> "Flight":
        return replace(self, signals={k: v for k, v in self.signals.items() if k not in names})

    def between(self, t0: float, t1: float) -> "Flight":
        """Only the samples with ``t0 <= t <= t1`` seconds (time stamps unchanged)."""
        return replace(self, signals={k: s.between(t0, t1) for k, s in self.signals.items()},
                       events=tuple(e for e in self.events if t0 <= e.t_s <= t1))

    def shifted(self, dt_s: float) -> "Flight":
        """Every time stamp, segment and event moved by ``dt_s`` seconds."""
        return replace(
            self,
            signals={k: s.shifted(dt_s) for k, s in self.signals.items()},
            segments={k: tuple((a + dt_s, b + dt_s) for a, b in v) for k, v in self.segments.items()},
            events=tuple(replace(e, t_s=e.t_s + dt_s) for e in self.events),
        )

    def summary(self) -> dict:
        """A JSON-ready summary (what ``droneid inspect --json`` prints)."""
        return {
            "files": list(self.provenance.files),
            "format": self.provenance.format,
            "vehicle": self.provenance.vehicle,
            "vehicle_type": self.provenance.vehicle_type,
            "vehicle_declared": self.provenance.vehicle_declared,
            "firmware": self.provenance.firmware,
            "duration_s": _r(self.duration_s),
            "signals": [
                {"name": s.name, "unit": s.unit, "rate_hz": _r(s.rate_hz), "count": len(s),
                 "start_s": _r(s.start_s), "end_s": _r(s.end_s), "source": s.source}
                for s in sorted(self.signals.values(), key=_signal_order)
            ],
            "segments": {k: [[_r(a), _r(b)] for a, b in v] for k, v in self.segments.items()},
            "events": [{"t_s": _r(e.t_s), "kind": e.kind, "text": e.text} for e in self.events],
            "notes": list(self.provenance.notes),
            "diagnostics": self.diagnostics.to_dict(),
        }


def _r(x: float, nd: int = 4):
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


_ORDER = {n: i for i, n in enumerate(CANONICAL_SIGNALS)}


def _signal_order(s: Signal):
    r = _rotor(s.name)
    if r:
        return (len(_ORDER) + list(ROTOR_SIGNALS).index(r[0]), r[1], s.name)
    return (_ORDER.get(s.name, len(_ORDER) + len(ROTOR_SIGNALS)), 0, s.name)


def fingerprint(flight: Flight) -> str:
    """A digest of a flight's data: every signal's name, time stamps (s) and values as read. Two
    flights with one fingerprint are the same data (one file given twice, or a copy of it)."""
    h = hashlib.blake2b(digest_size=16)
    for name in sorted(flight.signals):
        s = flight.signals[name]
        h.update(name.encode() + b"\0")
        h.update(np.ascontiguousarray(s.t).tobytes())
        h.update(np.ascontiguousarray(s.values).tobytes())
    return h.hexdigest()


def distinct_flights(train: Iterable[Flight], test: Iterable[Flight] = ()) -> tuple[list, list, list[str]]:
    """``(train, test, notes)``: each list with a flight whose data repeat an earlier one's
    (:func:`fingerprint`) kept once, and a note per flight left out. The same flight twice is one
    flight: counted twice it would double its blocks in every test and show "constant" across
    flights that are one. DataError when a test flight is the data of a training flight: it
    would test the model on what it was fitted to."""
    notes: list[str] = []

    def once(flights, what):
        kept, seen = [], {}
        for f in flights:
            key = fingerprint(f)
            if key in seen:
                notes.append(f"{_where(f)}: the same data as the {what} flight {_where(seen[key])}: read once")
                continue
            seen[key] = f
            kept.append(f)
        return kept, seen
    train, by_key = once(train, "training")
    test, _ = once(test, "test")
    for f in test:
        twin = by_key.get(fingerprint(f))
        if twin is not None:
            raise DataError(f"{_where(f)}: this test flight is the same data as the training flight "
                            f"{_where(twin)}; a test flight must be one the model is not fitted to")
    return train, test, notes


def _where(flight: Flight) -> str:
    """The flight's first file, else its name."""
    return flight.provenance.files[0] if flight.provenance.files else flight.name
