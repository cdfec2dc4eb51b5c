"""What kind of vehicle flew a log, judged from its data when the log does not say (issue 29):
whether it ever hovers, how far it tilts while still, whether its horizontal acceleration follows
its thrust axis (a multirotor's a_h = g·tan(tilt)), and how much it turns. The data-fitness check
(:mod:`droneid.dataset.suitability`) and ``inspect`` show this evidence and refuse a multirotor prior on data
that do not look like one. Speeds in m/s, accelerations in m/s², angles in degrees, times in s.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from droneid.logs.flight import Flight
from droneid.logs.in_flight import resample_signal
from droneid.core.numerics import rounded

__all__ = ["VehicleEvidence", "vehicle_evidence", "tilt_deg", "EVIDENCE_STEP_S", "HOVER_ACCEL_MS2", "HOVER_SPEED_MS", "MIN_HOVER_S", "NEVER_SLOW_MS",
           "MAX_HOVER_TILT_DEG", "MAX_TILT_MISMATCH_DEG", "MIN_EVIDENCE_S"]

#: vehicle evidence (:func:`vehicle_evidence`), on a 0.1 s grid over the airborne data:
#: hovering = horizontal speed below HOVER_SPEED_MS, |vz| below HOVER_SPEED_MS and horizontal
#: acceleration below HOVER_ACCEL_MS2; the mismatch = median angle between the horizontal
#: acceleration and g·tan(tilt) along the thrust axis, beyond its steady (wind) offset.
#: Measured: multirotors (ArduCopter log171 2.2 deg, mission1 2.7, PX4 x500 0.1, Crazyflie
#: 1.1-2.2, the simulated sample logs 1.3-4.5, a simulated hover in 6 m/s wind with gusts 3.9);
#: birds (OptiTrack) 12-33 deg; the fixed-wing 9.7 deg and never slower than 3.4 m/s, while a
#: multirotor flying a continuous figure eight (the sample logs) may stay above 0.8 m/s.
HOVER_SPEED_MS = 0.5
HOVER_ACCEL_MS2 = 1.0
MIN_HOVER_S = 1.0           # hover tilt is named in a refusal on at least this much hovering
NEVER_SLOW_MS = 2.0         # slowest (1st percentile) horizontal speed at or above: never hovers
MAX_HOVER_TILT_DEG = 10.0   # a still body tilted more than this is named in a refusal
MAX_TILT_MISMATCH_DEG = 8.0  # a multirotor's acceleration follows its thrust axis within this
MIN_EVIDENCE_S = 3.0        # less airborne data than this: no judgement
_G = 9.81
EVIDENCE_STEP_S = 0.1


# -- the vehicle, from the data ---------------------------------------------------------------
@dataclass(frozen=True)
class VehicleEvidence:
    """What the airborne data say about the vehicle (seconds, degrees, m/s).

    ``measured_s``: airborne seconds with velocity and attitude; ``hover_s``: of these, seconds
    hovering (slow and not accelerating, see the module constants); ``hover_tilt_deg``: median
    tilt from vertical while hovering; ``tilt_mismatch_deg``: median |tilt − atan(a_h/g)|;
    ``speed_ms``: (min, max) horizontal speed; ``tilt_max_deg``; ``yaw_span_deg`` (unwrapped);
    ``looks``: "multirotor", "not a multirotor" or "undecided"; ``reasons``: why (lines)."""
    measured_s: float
    hover_s: float
    hover_tilt_deg: float
    tilt_mismatch_deg: float
    speed_ms: tuple[float, float]
    tilt_max_deg: float
    yaw_span_deg: float
    looks: str
    reasons: tuple[str, ...] = ()

    def text(self) -> str:
        """One line of the measurements (and the reasons when not a multirotor)."""
        if self.looks == "undecided":
            return "; ".join(self.reasons) or "no airborne velocity and attitude"
        parts = [f"hovers {self.hover_s:.1f} s of {self.measured_s:.1f} s"]
        if math.isfinite(self.hover_tilt_deg):
            parts.append(f"tilt while hovering {self.hover_tilt_deg:.1f} deg")
        parts.append(f"horizontal speed {_fmt(self.speed_ms[0])}..{_fmt(self.speed_ms[1])} m/s")
        if math.isfinite(self.tilt_mismatch_deg):
            parts.append(f"tilt vs acceleration off by {self.tilt_mismatch_deg:.1f} deg")
        if math.isfinite(self.tilt_max_deg):
            parts.append(f"tilt up to {self.tilt_max_deg:.0f} deg")
        if math.isfinite(self.yaw_span_deg):
            parts.append(f"yaw turns {self.yaw_span_deg:.0f} deg")
        return ", ".join(parts)

    def to_dict(self) -> dict:
        return {"looks": self.looks, "reasons": list(self.reasons), "text": self.text(),
                "measured_s": rounded(self.measured_s),
                "hover_s": rounded(self.hover_s), "hover_tilt_deg": rounded(self.hover_tilt_deg),
                "tilt_mismatch_deg": rounded(self.tilt_mismatch_deg),
                "speed_ms": [rounded(x) for x in self.speed_ms], "tilt_max_deg": rounded(self.tilt_max_deg),
                "yaw_span_deg": rounded(self.yaw_span_deg)}


def _fmt(x, nd=2) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


def tilt_deg(roll, pitch):
    """Tilt of the body z axis from vertical (deg) from Z-Y-X roll and pitch (rad)."""
    with np.errstate(invalid="ignore"):
        return np.degrees(np.arccos(np.clip(np.cos(roll) * np.cos(pitch), -1.0, 1.0)))


def _thrust_axis(roll, pitch, yaw):
    """The body z axis (thrust direction) in the ENU world, from Z-Y-X roll, pitch, yaw (rad):
    the third column of Rz(yaw)·Ry(pitch)·Rx(roll), droneid's FLU/ENU convention."""
    cr, sr, cp, sp_, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return cy * sp_ * cr + sy * sr, sy * sp_ * cr - cy * sr, cp * cr


def vehicle_evidence(flight: Flight, intervals: Sequence[tuple[float, float]]) -> VehicleEvidence:
    """Judge from ``flight``'s data inside ``intervals`` (airborne, s) whether it flies like a
    multirotor (see the module doc and the constants for the rule and where it comes from).

    The tilt-vs-acceleration mismatch compares the horizontal acceleration with the one the
    thrust axis gives at constant height (g·z_h/z_z, a vector), less its median: a steady
    offset (wind, drag at cruise) is not a mismatch. Without yaw, magnitudes are compared."""
    nan2 = (math.nan, math.nan)
    if not flight.has("vx", "vy", "roll", "pitch"):
        return VehicleEvidence(0.0, 0.0, math.nan, math.nan, nan2, math.nan, math.nan, "undecided",
                               ("no velocity and attitude to judge from",))
    step = EVIDENCE_STEP_S
    has_yaw = flight.has("yaw")
    rows = []
    for a, b in intervals:
        t = np.arange(a, b, step)
        if t.size < 3:
            continue
        vx, vy = resample_signal(flight["vx"], t), resample_signal(flight["vy"], t)
        vz = resample_signal(flight["vz"], t) if flight.has("vz") else np.zeros(t.size)
        ax, ay = np.gradient(vx, t), np.gradient(vy, t)
        roll, pitch = resample_signal(flight["roll"], t), resample_signal(flight["pitch"], t)
        yaw = resample_signal(flight["yaw"], t) if has_yaw else np.zeros(t.size)
        zx, zy, zz = _thrust_axis(roll, pitch, yaw)
        rows.append(np.column_stack([np.hypot(vx, vy), np.abs(vz), np.hypot(ax, ay), tilt_deg(roll, pitch),
                                     ax - _G * zx / zz, ay - _G * zy / zz]))
    A = np.vstack(rows) if rows else np.empty((0, 6))
    A = A[np.all(np.isfinite(A), axis=1)]
    measured = A.shape[0] * step
    yaw_span = _yaw_span(flight, intervals)
    if measured < MIN_EVIDENCE_S:
        return VehicleEvidence(measured, 0.0, math.nan, math.nan, nan2, math.nan, yaw_span, "undecided",
                               (f"only {measured:.1f} s of airborne velocity and attitude to judge from",))
    speed, vz, ah, tilt, rx, ry = A.T
    hover = (speed < HOVER_SPEED_MS) & (vz < HOVER_SPEED_MS) & (ah < HOVER_ACCEL_MS2)
    hover_s = float(hover.sum() * step)
    hover_tilt = float(np.median(tilt[hover])) if hover.any() else math.nan
    if has_yaw:
        off = np.hypot(rx - np.median(rx), ry - np.median(ry))
        mismatch = float(np.degrees(np.arctan(np.median(off) / _G)))
    else:
        mismatch = float(np.median(np.abs(tilt - np.degrees(np.arctan(ah / _G)))))
    reasons = []
    slowest = float(np.percentile(speed, 1))
    if slowest >= NEVER_SLOW_MS:
        reasons.append(f"never hovers (horizontal speed {slowest:.2f} m/s at least)")
    if mismatch > MAX_TILT_MISMATCH_DEG:
        reasons.append(f"its tilt does not follow its acceleration (off by {mismatch:.0f} deg beyond a "
                       f"steady offset such as wind; a multirotor < {MAX_TILT_MISMATCH_DEG:g} deg)"
                       + (f"; it is still {hover_s:.1f} s tilted by {hover_tilt:.0f} deg"
                          if hover_s >= MIN_HOVER_S and hover_tilt > MAX_HOVER_TILT_DEG else ""))
    return VehicleEvidence(measured, hover_s, hover_tilt, mismatch, (float(speed.min()), float(speed.max())),
                           float(tilt.max()), yaw_span, "not a multirotor" if reasons else "multirotor",
                           tuple(reasons))


def _yaw_span(f: Flight, ivs) -> float:
    if not f.has("yaw"):
        return math.nan
    s = f["yaw"]
    spans = []
    for a, b in ivs:
        m = (s.t >= a) & (s.t <= b)
        if m.sum() >= 2:
            u = np.unwrap(s.values[m])
            spans.append(float(np.degrees(u.max() - u.min())))
    return max(spans) if spans else math.nan
