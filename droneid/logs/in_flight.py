"""Which part of a flight is flight: the in-flight intervals of a log (its segments, then ground
contact and crashes removed by detection), the gaps of a signal, and resampling a signal at given
times. Used by the dataset builder, the data-fitness check, predict and the rollout.

Times in s (each flight's own time base); intervals are (start, end) pairs; heights in m, speeds
in m/s, angles in rad (tilt thresholds in degrees, as named).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from droneid.logs.flight import Flight, Signal
from droneid.core.frames import wrap_angle

__all__ = ["Interval", "in_flight_intervals", "signal_gaps", "resample_signal", "subtract_intervals"]

Interval = tuple[float, float]
_EULER = ("roll", "pitch", "yaw")


# -- interval algebra ---------------------------------------------------------------------------
def _intersect(a: Sequence[Interval], b: Sequence[Interval]) -> list[Interval]:
    out = []
    for a0, a1 in a:
        for b0, b1 in b:
            lo, hi = max(a0, b0), min(a1, b1)
            if hi > lo:
                out.append((lo, hi))
    return sorted(out)


def subtract_intervals(a: Sequence[Interval], holes: Sequence[Interval]) -> list[Interval]:
    """The parts of intervals ``a`` outside every interval of ``holes`` (seconds)."""
    out = list(a)
    for h0, h1 in holes:
        nxt = []
        for a0, a1 in out:
            if h1 <= a0 or h0 >= a1:
                nxt.append((a0, a1))
                continue
            if h0 > a0:
                nxt.append((a0, h0))
            if h1 < a1:
                nxt.append((h1, a1))
        out = nxt
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) index pairs of the True runs of a boolean array (stop exclusive)."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _fmt_iv(ivs: Sequence[Interval]) -> str:
    return ", ".join(f"{a:.2f}-{b:.2f} s" for a, b in ivs) or "none"


# -- resampling ---------------------------------------------------------------------------------
def _is_angle(sig: Signal) -> bool:
    return sig.name in _EULER or sig.unit == "rad"


def resample_signal(sig: Signal, t: np.ndarray) -> np.ndarray:
    """``sig`` linearly interpolated at times ``t``; nan outside its time span.

    Angles (unit rad) are unwrapped before interpolation and wrapped to [-π, π) after when the
    original values were within [-π, π]."""
    t = np.asarray(t, dtype=np.float64)
    if len(sig) == 0:
        return np.full(t.shape, np.nan)
    v = sig.values
    wrapped = False
    if _is_angle(sig):
        wrapped = bool(np.all(np.abs(v) <= math.pi + 1e-6))
        v = np.unwrap(v)
    if len(sig) == 1:
        out = np.where(t == sig.t[0], v[0], np.nan)
    else:
        out = np.interp(t, sig.t, v, left=np.nan, right=np.nan)
    return wrap_angle(out) if wrapped else out


@dataclass(frozen=True)
class _Detect:
    """The detection settings (:class:`droneid.dataset.builder.DatasetBuilder` documents them;
    its defaults are these)."""
    min_height_m: float = 0.15
    still_speed: float = 0.3
    idle_fraction: float = 0.3
    min_segment_s: float = 1.0
    crash_tilt_deg: float = 60.0
    crash_hold_s: float = 0.5
    crash_accel: float = 60.0
    crash_margin_s: float = 0.5
    ground_margin_s: float = 0.2


#: how much of a log's start and end (s) tells the height it took off from or landed at
_END_S = 1.0
#: the shortest ground contact (s): a vehicle at rest stays there longer than a turnaround lasts
_REST_S = 0.5


def _grid_values(flight: Flight, name: str, t: np.ndarray):
    return resample_signal(flight[name], t) if flight.has(name) else None


def _speed(flight: Flight, t: np.ndarray) -> np.ndarray | None:
    """Speed (m/s) on grid ``t``, or None without vx, vy, vz."""
    if not flight.has("vx", "vy", "vz"):
        return None
    with np.errstate(over="ignore", invalid="ignore"):   # a damaged huge value: inf, not still
        return np.sqrt(sum(_grid_values(flight, n, t) ** 2 for n in ("vx", "vy", "vz")))


def _detect_ground(flight: Flight, t: np.ndarray, p: _Detect) -> tuple[np.ndarray | None, str]:
    """Ground mask on grid ``t`` (None when the flight has no cue for it) and a note.

    With a height that climbs well above its lowest point, and a log that starts or ends still at
    that point (before a take-off or after a landing), the vehicle is on the ground where it
    is within ``min_height_m`` of that point and either still (below ``still_speed``) or at idle
    power: resting on the ground with the motors spinning up for take-off is ground contact
    (the ground, not the thrust, holds the vehicle), whatever the power. Without such a height,
    ground is idle power and still together."""
    power = None
    for name in ("throttle", "thrust"):
        power = _grid_values(flight, name, t)
        if power is not None:
            break
    if power is None:
        motors = [_grid_values(flight, f"motor{i}", t) for i in range(1, 17) if flight.has(f"motor{i}")]
        if motors:
            m = np.column_stack(motors)        # mean of the motors with data (none: nan, no warning)
            n = np.isfinite(m).sum(axis=1)
            with np.errstate(over="ignore", invalid="ignore"):
                power = np.where(n > 0, np.nansum(m, axis=1) / np.maximum(n, 1), np.nan)
    idle = None
    if power is not None and np.isfinite(power).any():
        top = np.nanpercentile(power, 90)
        if top > 0:
            idle = np.nan_to_num(power, nan=np.inf) < p.idle_fraction * top  # no data: not a cue
    v = _speed(flight, t)
    still = None if v is None else np.nan_to_num(v, nan=np.inf) < p.still_speed
    low = None
    z = _grid_values(flight, "z", t)
    if z is not None and np.isfinite(z).any():
        z_ground = np.nanpercentile(z, 1)
        near = np.nan_to_num(z - z_ground, nan=np.inf) < p.min_height_m
        # only a log that climbs well above its lowest point, and rests there (starts or ends still
        # there, or idles there: before a take-off, after a landing), shows where the ground is; a
        # flight whose lowest point is a hover at altitude (stop-and-go legs) has no ground in it
        first, last = t <= t[0] + _END_S, t >= t[-1] - _END_S
        rests = [bool(np.mean(near[m]) > 0.5 and (v is None or (np.isfinite(v[m]).any()   # no speed: not still
                                                             and np.nanmedian(v[m]) < p.still_speed)))
                 for m in (first, last)]
        if idle is not None:
            rests.append(bool((near & idle).sum() * (t[1] - t[0] if t.size > 1 else 0) >= _END_S))
        if np.nanpercentile(z, 99) - z_ground > 3 * p.min_height_m and any(rests):
            low = near
    if low is None and idle is None:
        return None, "no power signal and no climb from a lowest height: ground time not detected"
    if low is not None:
        rest = [c for c in (idle, still) if c is not None]
        ground = low & np.logical_or.reduce(rest) if rest else low
        rest_names = [n for n, c in (("power", idle), ("speed", still)) if c is not None]
        used = "height" + (f" and {' or '.join(rest_names)}" if rest_names else "")
        return ground, f"ground detected from {used}"
    cues = [idle] + ([still] if still is not None else [])
    return np.logical_and.reduce(cues), f"ground detected from power{'+speed' if still is not None else ''}"


def _ground_holes(flight: Flight, ts: float, p: _Detect) -> tuple[list[Interval] | None, str]:
    """The ground-contact intervals of a flight (s), each widened by ``ground_margin_s`` on both
    sides (lift-off and touchdown: the ground still pushes), and how they were found."""
    step = min(0.1, ts)
    t = np.arange(flight.start_s, flight.end_s + step / 2, step)
    ground, why = _detect_ground(flight, t, p)
    if ground is None:
        return None, why
    m = p.ground_margin_s
    # resting takes time: a run shorter than _REST_S is a turnaround in the air (still for an
    # instant at low power), not ground contact
    return [(t[i0] - step / 2 - m, t[i1 - 1] + step / 2 + m) for i0, i1 in _runs(ground)
            if t[i1 - 1] - t[i0] + step >= _REST_S], why


def _crash_time(flight: Flight, ivs: Sequence[Interval], p: _Detect) -> tuple[float | None, str]:
    """The earliest crash time inside ``ivs`` and why, or (None, "")."""
    found = []
    for e in flight.events:
        if e.kind == "crash" and any(a <= e.t_s <= b for a, b in ivs):
            found.append((e.t_s, f"crash event at {e.t_s:.2f} s"))
    if flight.has("roll", "pitch"):
        t = flight["roll"].t
        tilt = np.degrees(np.maximum(np.abs(flight["roll"].values),
                                     np.abs(resample_signal(flight["pitch"], t))))
        inside = np.zeros(t.size, bool)
        for a, b in ivs:
            inside |= (t >= a) & (t <= b)
        for i0, i1 in _runs(np.nan_to_num(tilt) > p.crash_tilt_deg):
            if t[i1 - 1] - t[i0] >= p.crash_hold_s and inside[i0:i1].any():
                found.append((float(t[i0]), f"tilt above {p.crash_tilt_deg:g} deg for "
                                             f"{t[i1 - 1] - t[i0]:.2f} s from {t[i0]:.2f} s"))
                break
    if flight.has("ax", "ay", "az"):
        t = flight["ax"].t
        f = np.sqrt(flight["ax"].values ** 2 + resample_signal(flight["ay"], t) ** 2
                    + resample_signal(flight["az"], t) ** 2)
        big = np.flatnonzero(np.nan_to_num(f) > p.crash_accel)
        for i, j in zip(big[:-1], big[1:]):
            if t[j] - t[i] <= 0.2 and any(a <= t[i] <= b for a, b in ivs):
                found.append((float(t[i]), f"specific force above {p.crash_accel:g} m/s^2 "
                                           f"at {t[i]:.2f} s"))
                break
    if not found:
        return None, ""
    return min(found)


def in_flight_intervals(flight: Flight, *, ts: float = 0.05, detect: _Detect | None = None
                        ) -> tuple[list[Interval], list[str]]:
    """The airborne, pre-crash time intervals of a flight (seconds) and notes on how found."""
    p = detect or _Detect()
    span = [(flight.start_s, flight.end_s)]
    notes = []
    seg = flight.segments
    if seg.get("in_flight"):
        ivs = _intersect(span, seg["in_flight"])
        if seg.get("armed"):
            ivs = _intersect(ivs, seg["armed"])
        notes.append(f"in-flight part from the log's segments: {_fmt_iv(ivs)}")
    else:
        ivs = _intersect(span, seg["armed"]) if seg.get("armed") else span
        if seg.get("armed"):
            notes.append(f"armed part from the log's segments: {_fmt_iv(ivs)}")
    # a log's "flying" flag says the controller flies, not that the vehicle is off the ground:
    # ground contact is trimmed from the log's segments too
    holes, why = _ground_holes(flight, ts, p)
    if holes:
        kept = [iv for iv in subtract_intervals(ivs, holes) if iv[1] - iv[0] >= p.min_segment_s]
        notes.append(f"{why}; airborne: {_fmt_iv(kept)}")
        ivs = kept
    else:
        notes.append(why if holes is None else f"{why}: none found")
    t_crash, why = _crash_time(flight, ivs, p)
    if t_crash is not None:
        ivs = _intersect(ivs, [(-math.inf, t_crash - p.crash_margin_s)])
        notes.append(f"crash trimmed ({why}): data after {t_crash - p.crash_margin_s:.2f} s dropped")
    return ivs, notes


def signal_gaps(sig: Signal, max_gap_s: float) -> list[Interval]:
    """The time intervals (s) where ``sig`` has no sample for longer than ``max_gap_s`` or five
    median sample steps, whichever is longer (:meth:`Signal.gaps`, the rule rates and the
    data-fitness check use too)."""
    return sig.gaps(max_gap_s)


# -- the builder --------------------------------------------------------------------------------
