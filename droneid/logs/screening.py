"""Screening of implausible samples: telemetry glitches never reach a fit.

A log can carry samples that no vehicle can produce: a motor speed at 10-40x the motors'
maximum for one sample (a radio or logging fault), a motion-capture position that jumps by half a
metre in 10 ms (a marker swap), a burst of NaN. :func:`screen_signal` finds them in one signal of
one flight by a robust, documented rule, and returns the time intervals that no grid row may use.

The rule, per signal, on its raw samples (non-finite samples and bad stamps are already dropped
by :meth:`droneid.logs.flight.Signal.clean` and counted in the log's diagnostics):

1. **Physical range.** A sample outside :data:`PHYSICAL_RANGE` of its kind (a motor speed below
   0 rpm, a battery voltage at or below 0 V) is implausible.
2. **Robust range.** With ``lo``/``hi`` the 0.5th/99.5th percentiles of the flight and
   ``w = max(hi - lo, BAND_FLOOR·max(|lo|, |hi|))``, a sample outside
   ``[lo - RANGE_WIDTHS·w, hi + RANGE_WIDTHS·w]`` is implausible.
   At most 1 % of the samples lie outside [lo, hi] by construction, and a real signal does not
   leave its own 99 % band by three band widths; a glitch at 10x the maximum does. Angles are
   exempt (a wrapped or unwrapped yaw has no robust band).
3. **Jumps.** The rate of change between two consecutive samples, ``|Δx| / Δt``, above
   ``JUMP_FACTOR`` times the 99th percentile of the flight's own rates, is a jump that no motor or
   vehicle makes in one sample. Nothing is interpolated or differentiated across it. Angles are
   unwrapped first; quaternion components are not screened (their sign flips are not jumps; the
   Euler angles derived from them are).

An implausible sample ``i`` makes the interval ``(t[i-1], t[i+1])`` a hole; a jump between ``i``
and ``i+1`` makes ``(t[i], t[i+1])`` one. Jumps come in clusters (a marker swap makes several
jumps in 0.1 s, with garbage between them): jump holes closer than ``MERGE_S`` are merged, and
widened by ``PAD_S`` on both sides. The dataset builder leaves out every row whose
differentiator stencil reaches a hole (for a spline, which smooths a whole interval, the holes of
the target's source are cut from the intervals), so rows that depend on a screened sample (by
interpolation or by a derivative) are left out of fitting, validation, test and prediction, never
interpolated across. The statistics are those of the whole flight: with ``--holdout`` they include
the held-out block (a data-quality rule, not a model choice; nothing is fitted to choose them).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from droneid.logs.flight import Flight, Signal

__all__ = ["Screen", "screen_signal", "screen_flight", "PHYSICAL_RANGE", "RANGE_WIDTHS",
           "JUMP_FACTOR", "MERGE_S", "PAD_S", "MIN_SCREENED_SAMPLES", "implausible_counts"]

#: robust-range margin, in widths of the 0.5-99.5 % band
RANGE_WIDTHS = 3.0
#: the band is at least this fraction of the signal's level (a throttle held at 0.5 that steps to
#: 0.6 is no glitch; one at 5.0 is)
BAND_FLOOR = 0.25
#: a one-sample rate of change above this many times the flight's 99th percentile is a jump
JUMP_FACTOR = 5.0
#: holes closer than this (s) are one glitch: merged, nothing in between is trusted
MERGE_S = 0.1
#: each merged hole is widened by this much (s) on both sides, so that no difference at the new
#: edge of the data spans a glitch's neighbours (one grid period at the default Ts)
PAD_S = 0.05
#: signals with fewer samples are not screened (too few for the robust median/MAD statistics);
#: not the dataset minimum (:data:`droneid.dataset.suitability.MIN_SAMPLES`, grid samples in flight)
MIN_SCREENED_SAMPLES = 20
#: physical bounds by signal-name prefix: (lowest, highest) plausible value in the signal's unit
PHYSICAL_RANGE: Mapping[str, tuple[float, float]] = {
    "rpm": (0.0, np.inf),        # motor speed (rpm or eRPM): never negative
    "battery_voltage": (1e-9, np.inf),  # (V): a flying vehicle has a positive voltage
}
_NOT_SCREENED = ("qw", "qx", "qy", "qz")

Interval = tuple[float, float]


@dataclass(frozen=True)
class Screen:
    """What screening found in one signal of one flight.

    name : the signal; n : its samples; out_of_range : samples outside the physical or robust
    range; jumps : one-sample changes faster than the rule allows; holes : time intervals (s,
    the flight's time base) that no grid row may use; band : the robust range (lo, hi) used
    """
    name: str
    n: int
    out_of_range: int = 0
    jumps: int = 0
    holes: tuple[Interval, ...] = ()
    band: tuple[float, float] = (-np.inf, np.inf)

    @property
    def implausible(self) -> int:
        """Samples and jumps screened out (what the reports count as "implausible")."""
        return self.out_of_range + self.jumps

    def describe(self) -> str:
        parts = []
        if self.out_of_range:
            parts.append(f"{self.out_of_range} sample(s) outside [{self.band[0]:.4g}, {self.band[1]:.4g}]")
        if self.jumps:
            parts.append(f"{self.jumps} jump(s) faster than {JUMP_FACTOR:g}x the flight's 99th-percentile rate")
        return f"{self.name}: " + ", ".join(parts) if parts else f"{self.name}: clean"


def _physical(name: str) -> tuple[float, float]:
    for prefix, bounds in PHYSICAL_RANGE.items():
        if name.startswith(prefix):
            return bounds
    return (-np.inf, np.inf)


def screen_signal(sig: Signal) -> Screen:
    """Screen one signal by the module's rule (see the module docstring)."""
    n = len(sig)
    if n < MIN_SCREENED_SAMPLES or sig.name in _NOT_SCREENED:
        return Screen(sig.name, n)
    t = np.asarray(sig.t, float)
    v = np.asarray(sig.values, float)
    angle = sig.name in ("roll", "pitch", "yaw") or sig.unit == "rad"
    plo, phi = _physical(sig.name)
    bad = (v < plo) | (v > phi)
    lo, hi = -np.inf, np.inf
    if not angle:
        p_lo, p_hi = np.percentile(v[~bad] if (~bad).any() else v, [0.5, 99.5])
        # a nearly constant signal has no band to speak of: at least a quarter of its level
        w = max(p_hi - p_lo, BAND_FLOOR * max(abs(p_lo), abs(p_hi)), 1e-9)
        lo, hi = max(p_lo - RANGE_WIDTHS * w, plo), min(p_hi + RANGE_WIDTHS * w, phi)
        bad |= (v < lo) | (v > hi)
    else:
        v = np.unwrap(v)
    holes = [(float(t[max(i - 1, 0)]), float(t[min(i + 1, n - 1)])) for i in np.flatnonzero(bad)]
    jump_holes = []
    rate = np.abs(np.diff(v)) / np.maximum(np.diff(t), 1e-12)
    ok = ~(bad[1:] | bad[:-1])       # rates between plausible samples
    jumps = np.zeros(n - 1, dtype=bool)
    if ok.sum() >= MIN_SCREENED_SAMPLES:
        q = float(np.percentile(rate[ok], 99))
        if q > 0:
            jumps = ok & (rate > JUMP_FACTOR * q)
    jump_holes = [(float(t[i]), float(t[i + 1])) for i in np.flatnonzero(jumps)]
    return Screen(sig.name, n, int(bad.sum()), int(jumps.sum()), _merged(holes, jump_holes),
                  (float(lo), float(hi)))


def _merged(samples, jumps) -> tuple[Interval, ...]:
    """Holes of bad samples as they are; holes of jumps merged into clusters (closer than
    MERGE_S) and padded by PAD_S (a jump leaves garbage around it, a lone out-of-range sample
    does not); then every overlap merged."""
    out: list[list[float]] = []
    for a, b in sorted(jumps):
        if out and a - out[-1][1] < MERGE_S:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    merged: list[list[float]] = []
    for a, b in sorted([*samples, *((a - PAD_S, b + PAD_S) for a, b in out)]):
        if merged and a <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return tuple((a, b) for a, b in merged)


def screen_flight(flight: Flight, names=None) -> dict[str, Screen]:
    """{signal: Screen} for ``names`` (default: every signal of the flight)."""
    names = flight.names if names is None else [n for n in names if flight.has(n)]
    return {n: screen_signal(flight[n]) for n in names}


def implausible_counts(screens: Mapping[str, Screen]) -> dict[str, int]:
    """{signal: implausible count} of the signals where screening found something."""
    return {n: s.implausible for n, s in screens.items() if s.implausible}
