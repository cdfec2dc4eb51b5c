"""Consistency of redundant signals: a log read in the wrong convention is named, not fitted
(issue 41).

A flight log carries the same motion several times: velocity and the derivative of position;
body rates and the derivative of the attitude; the thrust direction (attitude) and the horizontal
acceleration; the thrust (rotor signals, accelerometer) and the vertical acceleration; gravity in
the accelerometer. A convention mistake (NED read as ENU, FRD rates, milliseconds read as
seconds, km/h, deg/s, x and y swapped, yaw turning clockwise) breaks one of these relations in a
recognisable way: a slope of 3.6, 57.3 or 1000 where 1 is expected, a sign, a swap of axes.
:func:`check_flight` measures each relation and names each mismatch in one line with the reader
option that fixes it (:class:`Finding`); identify and diagnose refuse such data before any fit
(:func:`raise_if_inconsistent`, called by :func:`droneid.dataset.suitability.check_prior_data`), and
``droneid inspect`` shows the findings.

Every relation is measured on a uniform grid (the slower signal's median step) over the time
where all its signals have data (bursts, never across a gap), both sides smoothed by the same
moving average; the slope is a Huber fit through the medians (:func:`droneid.core.regression.robust_fit`),
the correlation is weighted by the fit's weights. A relation is judged only when its two sides
correlate strongly (:data:`STRONG_CORR` in absolute value) over at least :data:`MIN_POINTS`
samples; otherwise it is skipped with the reason (no motion, a ground test, slow telemetry).

Thresholds were calibrated on every log of ``../shared/real_logs`` and the simulated sample logs
(per-log values: docs/logs.md, "Convention checks"). What consistent logs measure, and what is named:

* **velocity vs position**, ``v ≈ s·dp/dt`` per axis: s = 0.88-1.04 where r >= 0.85. Named:
  s ≈ 3.6 (km/h), s ≈ -1 (a sign), a velocity following another axis's position (a swap).
* **body rates vs attitude**, ``w ≈ s·ω`` per FLU axis, ω from the Euler angles' rates
  (:func:`droneid.core.frames.body_rates_from_euler`): s = 0.88-1.09 (0.32-0.64 on wz of the PX4 VTOL
  and ground test: positive, not named). Named: s ≈ 57.3 (deg/s); wy and wz reversed (FRD);
  wz alone reversed (yaw negated). Needs >= :data:`MIN_RATE_HZ`.
* **horizontal acceleration vs thrust axis**: ``d(vx, vy)/dt`` against ``g·(zx, zy)/zz`` (a
  multirotor's a_h = g·tan(tilt)), a vector correlation as read (0.62-0.98 on the moving
  multirotors, 0.91 on the fixed-wing's pose), with x/y swapped, with yaw negated; an alternative
  must reach :data:`ALT_SCORE` and beat "as read" by :data:`ALT_MARGIN` (a yaw near 0 scores
  "yaw negated" almost as high as "as read"). Birds, and log171 with its crash, score low every way.
* **vertical**: the accelerometer rotated to the world (else Σ rpm², Σ motor, throttle) against
  ``d(vz)/dt``: r = 0.71-0.99; r <= -:data:`VERTICAL_CORR` is z down (with the x/y swap: NED).
* **gravity**: median ``az`` 9.58-9.84 m/s²; about -g is an FRD accelerometer, about 1 one in g.
* **time**: a slope of 1000^k (velocity or rates) on every moving axis, or a horizontal
  acceleration 1000^-2k x g·tan(tilt) (the gain is 0.49-0.94 on the real logs), is a time base in
  ms/µs/ns: "a 69.7 s flight read as 69,720 s".
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from droneid.core.differentiation import CentralDifference
from droneid.errors import ConventionError
from droneid.logs.flight import Flight
from droneid.core.frames import body_rates_from_euler, euler_to_matrix
from droneid.logs.in_flight import resample_signal
from droneid.logs.signal_grid import grids, lag_of, on_grid, rate_of, smooth, step_of, window
from droneid.core.regression import robust_fit

__all__ = ["Check", "Finding", "Consistency", "check_flight", "check_flights", "raise_if_inconsistent",
           "ConventionError", "STRONG_CORR", "MIN_POINTS", "MIN_RATE_HZ", "ALT_SCORE", "ALT_MARGIN",
           "VERTICAL_CORR", "OK_SLOPE"]

G = 9.81
#: a relation is judged only where its two sides correlate at least this much (absolute value)
STRONG_CORR = 0.8
#: fewest grid samples a relation is judged on
MIN_POINTS = 50
#: attitude, rates, velocity slower than this (Hz) are not differentiated for a check
MIN_RATE_HZ = 5.0
#: a slope within this band is consistent (real logs: 0.88-1.09 where judged)
OK_SLOPE = (0.6, 1.6)
#: known factors: (low, high, what it means)
_KMH = (3.0, 4.3)
_DEG = (45.0, 72.0)
#: a reversed sign: -slope within this band (a yaw negated in the attitude leaves wz at -0.45 x
#: the attitude's rate on the aggressive Crazyflie squares, where the roll/pitch terms of the
#: Euler kinematics do not change sign)
_SIGN_SLOPE = (0.3, 1.6)
#: the horizontal check: an alternative reading must score at least ALT_SCORE and beat the
#: reading as read by ALT_MARGIN (vector correlations, -1..1)
ALT_SCORE = 0.5
ALT_MARGIN = 0.4
#: the vertical check: a correlation of thrust and d(vz)/dt at or below -VERTICAL_CORR says z is down
VERTICAL_CORR = 0.5
#: moving-average windows (s) of the derivative relations and of the acceleration relations
SMOOTH_S = 0.1
ACCEL_SMOOTH_S = 0.3
_TIME_UNITS = {1: ("ms", "milliseconds"), 2: ("us", "microseconds"), 3: ("ns", "nanoseconds")}


@dataclass(frozen=True)
class Check:
    """One relation: ``name``; ``status`` "ok", "mismatch" or "skipped"; ``detail`` the
    measurement or the reason it was skipped; ``numbers`` the slopes/correlations measured."""
    name: str
    status: str
    detail: str
    numbers: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "numbers", MappingProxyType(dict(self.numbers)))

    def to_dict(self) -> dict:
        return {"name": self.name, "status": self.status, "detail": self.detail,
                "numbers": {k: (round(float(v), 4) if math.isfinite(v) else None) for k, v in self.numbers.items()}}


@dataclass(frozen=True)
class Finding:
    """A convention mistake: ``text`` says what the data show, ``fix`` the reader options that
    correct it (command-line words), ``kind`` a short key (``time``, ``kmh``, ``deg``, ``ned``,
    ``frd``, ``swap``, ``yaw``, ``sign``, ``scale``, ``gravity``)."""
    kind: str
    text: str
    fix: str

    def line(self) -> str:
        return f"{self.text} ({self.fix})" if self.fix else self.text


@dataclass(frozen=True)
class Consistency:
    """The checks of one flight (``flight``: its file, or its name) and the findings."""
    flight: str
    checks: tuple[Check, ...]
    findings: tuple[Finding, ...]

    @property
    def ok(self) -> bool:
        return not self.findings

    def lines(self) -> list[str]:
        """One line per finding, naming the file: ``"FILE: TEXT (FIX)"``."""
        return [f"{self.flight}: {f.line()}" for f in self.findings]

    def to_dict(self) -> dict:
        return {"flight": self.flight, "ok": self.ok,
                "findings": [{"kind": f.kind, "text": f.text, "fix": f.fix, "line": f.line()} for f in self.findings],
                "checks": [c.to_dict() for c in self.checks]}


# -- relations ----------------------------------------------------------------------------------
def _relate(meas: np.ndarray, ref: np.ndarray) -> tuple[float, float, int]:
    """(slope, correlation, n) of ``meas ≈ slope·ref`` about their medians: a Huber fit (robust
    to glitches), the correlation weighted by its weights; (nan, nan, n) when too few samples or
    the reference does not move."""
    ok = np.isfinite(meas) & np.isfinite(ref)
    n = int(ok.sum())
    if n < MIN_POINTS:
        return math.nan, math.nan, n
    m, r = meas[ok] - np.median(meas[ok]), ref[ok] - np.median(ref[ok])
    if not np.std(r) > 0 or not np.std(m) > 0:
        return math.nan, math.nan, n
    fit = robust_fit(r[:, None], m)
    w = fit.weights
    mw, rw = m - np.average(m, weights=w), r - np.average(r, weights=w)
    den = math.sqrt(float(np.sum(w * mw * mw) * np.sum(w * rw * rw)))
    corr = float(np.sum(w * mw * rw) / den) if den > 0 else math.nan
    return float(fit.beta[0]), corr, n


def _power_of_1000(slope: float) -> int:
    """k when ``slope`` is 1000^k within ±25 % (k >= 1), else 0."""
    if not (math.isfinite(slope) and slope > 0):
        return 0
    k = round(math.log10(slope) / 3)
    return k if k >= 1 and abs(math.log10(slope) - 3 * k) < math.log10(1.25) else 0


def _in(x, band) -> bool:
    return math.isfinite(x) and band[0] <= x <= band[1]


def _may_be(slope: float, corr: float, band) -> bool:
    """Whether a slope fitted as ``meas ≈ slope·ref`` with correlation ``corr`` (> 0) may lie in
    ``band`` whichever of the two carries the noise: noise in the reference (a position's
    derivative is noisy) shrinks the fitted slope by corr², so the slope is anywhere in
    [slope, slope/corr²] (the forward and the reverse regression). Seen: a simulated flight with
    centimetres of position noise at 100 Hz and its velocity right read "vx is 0.60 x d(x)/dt"
    at r 0.8 and was refused as a unit mistake."""
    if not (math.isfinite(slope) and math.isfinite(corr) and corr > 0):
        return _in(slope, band)
    lo, hi = sorted((slope, slope / (corr * corr)))
    return lo <= band[1] and hi >= band[0]


def _derived(flight, n) -> bool:
    return flight[n].source.startswith("d/dt")


def _too_slow(flight: Flight, names) -> str:
    """The signals of ``names`` logged slower than MIN_RATE_HZ, as text ('' when none)."""
    slow = [f"{n} {flight[n].rate_hz:.1f} Hz" for n in names if flight.has(n) and not flight[n].rate_hz >= MIN_RATE_HZ]
    return f"logged too slowly ({', '.join(slow)} < {MIN_RATE_HZ:g} Hz)" if slow else ""


# -- the checks -------------------------------------------------------------------------------------
def _velocity_position(flight: Flight):
    """velocity against the derivative of position, per axis, and across axes (swaps)."""
    name = "velocity vs position"
    axes = [(p, v) for p, v in (("x", "vx"), ("y", "vy"), ("z", "vz")) if flight.has(p, v) and not _derived(flight, v)]
    if not axes:
        why = "velocity derived from position" if flight.has("vx") else "no position and velocity"
        return Check(name, "skipped", why), {}
    names = [n for pv in axes for n in pv]
    h = step_of(flight, names)
    k = window(h, SMOOTH_S)
    cols = {n: [] for n in names}
    dcols = {p: [] for p, _ in axes}
    for t in grids(flight, names, h, k):
        for p, v in axes:
            cols[v].append(smooth(on_grid(flight, v, t), k))
            dcols[p].append(rate_of(flight, p, t, k))
    if not dcols[axes[0][0]]:
        return Check(name, "skipped", "no stretch where position and velocity both have data"), {}
    V = {v: np.concatenate(cols[v]) for _, v in axes}
    D = {p: np.concatenate(dcols[p]) for p, _ in axes}
    res = {}
    for p, v in axes:
        res[v] = {q: _relate(V[v], D[q]) for q, _ in axes}
    lags = {v: lag_of(V[v], D[p], h) for p, v in axes}
    numbers = ({f"{v}/d{p}": res[v][p][0] for p, v in axes} | {f"corr {v},d{p}": res[v][p][1] for p, v in axes}
               | {f"lag {v} s": lag for v, lag in lags.items()})
    return None, {"axes": axes, "res": res, "numbers": numbers, "lags": lags}


_RATES = ("roll", "pitch", "yaw", "wx", "wy", "wz")
_HORIZONTAL = ("vx", "vy", "roll", "pitch", "yaw")


def _rates_attitude(flight: Flight):
    """body rates against the attitude's rates (at any rate: the judge skips slow signals
    unless the time base is in question)."""
    need = _RATES
    if not flight.has(*need):
        return Check("body rates vs attitude", "skipped", "no body rates and attitude"), {}
    h = step_of(flight, need)
    k = window(h, SMOOTH_S)
    meas, ref = [], []
    for t in grids(flight, need, h, k):
        e = np.column_stack([on_grid(flight, n, t, angle=True) for n in ("roll", "pitch", "yaw")])
        de = np.column_stack([CentralDifference()(np.nan_to_num(e[:, i]), t) for i in range(3)])
        w_att = body_rates_from_euler(e, de)
        ref.append(np.column_stack([smooth(w_att[:, i], k) for i in range(3)]))
        meas.append(np.column_stack([smooth(on_grid(flight, n, t), k) for n in ("wx", "wy", "wz")]))
    if not meas:
        return Check("body rates vs attitude", "skipped", "no stretch where attitude and rates both have data"), {}
    M, R = np.vstack(meas), np.vstack(ref)
    res = {n: _relate(M[:, i], R[:, i]) for i, n in enumerate(("wx", "wy", "wz"))}
    numbers = {f"{n}/att": r[0] for n, r in res.items()} | {f"corr {n},att": r[1] for n, r in res.items()}
    return None, {"res": res, "numbers": numbers}


def _horizontal(flight: Flight):
    name = "horizontal acceleration vs thrust axis"
    need = _HORIZONTAL
    if not flight.has(*need):
        return Check(name, "skipped", "no horizontal velocity and attitude"), {}
    h = step_of(flight, need)
    if not h > 0:
        return Check(name, "skipped", "fewer than 2 time-ordered samples"), {}
    # a step of 0.2 s or more is smoothed as if it were ms (µs, ns): only the time check, which
    # compares the gain with 1000^-2k, uses the result of such slow data
    k = window(h / 1000 ** max(0, math.ceil(math.log10(h / 0.2) / 3)), ACCEL_SMOOTH_S)
    A, P, Pn = [], [], []
    for t in grids(flight, need, h, k):
        ax, ay = (rate_of(flight, n, t, k) for n in ("vx", "vy"))
        r, p, y = (on_grid(flight, n, t, angle=True) for n in ("roll", "pitch", "yaw"))
        for out, yy in ((P, y), (Pn, -y)):
            z = euler_to_matrix(r, p, yy)[..., :, 2]      # the body z axis in the world
            out.append(smooth(G * (z[:, 0] + 1j * z[:, 1]) / z[:, 2], k))
        A.append(ax + 1j * ay)
    if not A:
        return Check(name, "skipped", "no stretch where velocity and attitude both have data"), {}
    A, P, Pn = np.concatenate(A), np.concatenate(P), np.concatenate(Pn)
    ok = np.isfinite(A) & np.isfinite(P) & np.isfinite(Pn)
    if ok.sum() < MIN_POINTS:
        return Check(name, "skipped", f"only {int(ok.sum())} samples"), {}
    A, P, Pn = A[ok], P[ok], Pn[ok]

    def score(a, p):      # a vector correlation about the medians (a steady wind is no mismatch)
        a, p = (z - (np.median(z.real) + 1j * np.median(z.imag)) for z in (a, p))
        den = math.sqrt(float(np.sum(np.abs(a) ** 2) * np.sum(np.abs(p) ** 2)))
        return float(np.sum(a * np.conj(p)).real / den) if den > 0 else math.nan
    swapped = A.imag + 1j * A.real
    s = {"as read": score(A, P), "x/y swapped": score(swapped, P), "yaw negated": score(A, Pn)}
    gain = float(np.sum(A * np.conj(P)).real / np.sum(np.abs(P) ** 2))      # 0.49-0.94 on the real logs
    return None, {"scores": s, "gain": gain, "numbers": {f"score {k_}": v for k_, v in s.items()} | {"gain": gain}}


def _vertical(flight: Flight, acc_frd: bool = False):
    name = "vertical acceleration vs thrust"
    if not flight.has("vz"):
        return Check(name, "skipped", "no vz"), {}
    body = ("ax", "ay", "az", "roll", "pitch", "yaw")
    rpm, mot = ([f"{p}{i}" for i in range(1, 17) if flight.has(f"{p}{i}")] for p in ("rpm", "motor"))
    for src, names in (("the accelerometer rotated to the world", list(body) if flight.has(*body) else []),
                       ("Σ rpm²", rpm), ("Σ motor commands", mot),
                       ("throttle", ["throttle"] if flight.has("throttle") else [])):
        if names:         # the first thrust signal the log has, in this order
            break
    else:
        return Check(name, "skipped", "no accelerometer or rotor signal"), {}
    need = ["vz", *names]
    if _too_slow(flight, need):
        return Check(name, "skipped", _too_slow(flight, need)), {}
    h = step_of(flight, need)
    k = window(h, ACCEL_SMOOTH_S)
    U, D = [], []
    for t in grids(flight, need, h, k):
        D.append(rate_of(flight, "vz", t, k))
        if src.startswith("the acc"):
            a = np.column_stack([on_grid(flight, n, t) for n in ("ax", "ay", "az")])
            if acc_frd:         # the gravity check found an FRD accelerometer: judge it as FLU
                a[:, 1:] *= -1.0
            # the world z component of R·a (R body to world): R's third row
            R = euler_to_matrix(*(on_grid(flight, n, t, angle=True) for n in ("roll", "pitch", "yaw")))
            u = np.einsum("nj,nj->n", R[:, 2, :], a)
        else:
            vals = np.column_stack([on_grid(flight, n, t) for n in names])
            u = np.sum(vals ** 2, axis=1) if src.startswith("Σ rpm") else np.sum(vals, axis=1)
        U.append(smooth(u, k))
    if not U:
        return Check(name, "skipped", "no stretch where vz and the thrust both have data"), {}
    slope, corr, n = _relate(np.concatenate(U), np.concatenate(D))
    return None, {"src": src, "corr": corr, "n": n, "numbers": {"corr thrust,dvz": corr}}


def _gravity(flight: Flight):
    name = "gravity in the accelerometer"
    if not flight.has("ax", "ay", "az"):
        return Check(name, "skipped", "no accelerometer"), None
    az = float(np.median(flight["az"].values))
    norm = float(np.median(np.sqrt(sum(resample_signal(flight[n], flight["az"].t) ** 2 for n in ("ax", "ay", "az")))))
    return None, {"az": az, "norm": norm}


# -- the verdict ---------------------------------------------------------------------------------
def _fmt_slope(s: float) -> str:
    return f"{s:.3g}" if abs(s) >= 100 else f"{s:.2f}"


def _column_swap_fix(flight: Flight) -> str:
    """``--column`` words that swap x/y and vx/vy back, from the signals' sources (flat CSV),
    else a statement that the log must be fixed at its source."""
    if flight.provenance.format != "csv":
        return "swap x and y (and vx, vy) where the log is written: no reader option of this format does"
    words = []
    for a, b in (("x", "y"), ("vx", "vy")):
        if flight.has(a, b) and not _derived(flight, a):
            words += [f"--column {a}={flight[b].source}", f"--column {b}={flight[a].source}"]
    return " ".join(words)


def check_flight(flight: Flight) -> Consistency:
    """Measure every relation of ``flight`` and name each convention mistake (see the module
    doc). Pure: never raises on bad data, never prints."""
    label = flight.provenance.files[0] if flight.provenance.files else flight.name
    checks: list[Check] = []
    findings: list[Finding] = []
    with np.errstate(all="ignore"):
        _judge(flight, checks, findings)
    return Consistency(label, tuple(checks), tuple(findings))


def _judge(flight, checks, findings) -> None:
    # 1. the time base: a slope of 1000^k in both derivative relations (velocity vs position,
    # rates vs attitude) on every axis that moves
    skip_vp, vp = _velocity_position(flight)
    skip_ra, ra = _rates_attitude(flight)
    skip_hz, hz = _horizontal(flight)
    time_k, time_evidence = 0, []
    for rel, what in ((vp, "d({p})/dt"), (ra, "the attitude's rate")):
        if not rel:
            continue
        pairs = ([(v, rel["res"][v][p], p) for p, v in rel["axes"]] if "axes" in rel else
                 [(n, r, "") for n, r in rel["res"].items()])
        strong = [(n, r, p) for n, r, p in pairs if r[1] >= STRONG_CORR]
        if strong:
            k_ = _power_of_1000(float(np.median([r[0] for _, r, _ in strong])))
            if k_ and (not time_k or k_ == time_k):
                time_k = k_
                n0, r0, p0 = strong[0]
                time_evidence.append(f"{n0} is {_fmt_slope(r0[0])} x {what.format(p=p0)}")
    # without velocity and rates: the acceleration is 1000^-2k x the tilt's g·tan(tilt)
    if not time_k and hz and hz["scores"]["as read"] >= ALT_SCORE and hz["gain"] > 0:
        k_ = round(-math.log10(hz["gain"]) / 6)
        if k_ >= 1 and abs(math.log10(hz["gain"]) + 6 * k_) < math.log10(5):
            time_k = k_
            time_evidence.append(f"d(vx, vy)/dt is {hz['gain']:.2g} x g·tan(tilt)")
    if time_k:
        unit, word = _TIME_UNITS[time_k]
        span = flight.duration_s
        findings.append(Finding("time", f"time stamps look like {word} ({'; '.join(time_evidence)}; a "
                                f"{span / 1000 ** time_k:.1f} s flight read as {span:,.0f} s)",
                                f"--time-unit {unit}"))
    for name, need in (("body rates vs attitude", _RATES), ("horizontal acceleration vs thrust axis", _HORIZONTAL)):
        if not time_k and flight.has(*need) and _too_slow(flight, need):      # too slow to differentiate
            skip = Check(name, "skipped", _too_slow(flight, need))
            skip_ra, skip_hz = (skip, skip_hz) if need is _RATES else (skip_ra, skip)
    # 2. velocity vs position
    if skip_vp:
        checks.append(skip_vp)
    else:
        res, axes = vp["res"], vp["axes"]
        strong = {v: res[v][p] for p, v in axes if res[v][p][1] >= STRONG_CORR}
        before = len(findings)
        kmh = [v for v, (s, _, _) in strong.items() if _in(s, _KMH)]
        if not time_k and kmh:
            v0 = kmh[0]
            findings.append(Finding("kmh", f"{v0} is {strong[v0][0]:.2f} x d({v0[1:]})/dt: velocity in km/h?",
                                    " ".join(f"--scale {v}=1/3.6" for _, v in axes)))
        for p, v in axes:
            s, c, n = res[v][p]
            if time_k or v in kmh:
                continue
            if c >= STRONG_CORR and not _may_be(s, c, OK_SLOPE):
                findings.append(Finding("scale", f"{v} is {_fmt_slope(s)} x d({p})/dt: {v} and {p} in different units?",
                                        f"--scale {v}={1 / s:.4g}"))
            elif c <= -STRONG_CORR and _in(-s, _SIGN_SLOPE):
                findings.append(Finding("sign", f"{v} is {s:.2f} x d({p})/dt: {v} and {p} have opposite signs",
                                        f"--scale {v}=-1, or --scale {p}=-1 if {p} is the one reversed"))
            elif abs(c) < STRONG_CORR / 2:
                other = [(res[v][q][1], q) for q, _ in axes if q != p and res[v][q][1] >= STRONG_CORR]
                if other:
                    c2, q = max(other)
                    findings.append(Finding("swap", f"{v} follows d({q})/dt (correlation {c2:.2f}), not d({p})/dt "
                                            f"({c:.2f}): velocity and position axes differ",
                                            f"map the velocity columns to the position's axes (--column v{q}=COLUMN)"))
        moving = [v for p, v in axes if abs(res[v][p][1]) >= STRONG_CORR]
        detail = ", ".join(f"{v} = {_fmt_slope(res[v][p][0])} x d({p})/dt (r {res[v][p][1]:.2f}"
                           + (f", {vp['lags'][v]:.3g} s behind)" if abs(res[v][p][1]) >= STRONG_CORR else
                              ": too weak to judge)")
                           for p, v in axes if math.isfinite(res[v][p][0]))
        if not moving:
            checks.append(Check("velocity vs position", "skipped",
                                f"too little motion to judge ({detail or 'no samples'})", vp["numbers"]))
        else:
            checks.append(Check("velocity vs position", "mismatch" if time_k or len(findings) > before else "ok",
                                detail, vp["numbers"]))
    # 3. body rates vs attitude
    frd = yaw_neg = False
    if skip_ra:
        checks.append(skip_ra)
    else:
        res = ra["res"]
        strong = {n: r for n, r in res.items() if abs(r[1]) >= STRONG_CORR}
        detail = ", ".join(f"{n} = {_fmt_slope(r[0])} x the attitude's rate (r {r[1]:.2f})" for n, r in res.items()
                           if math.isfinite(r[0]))
        mism = False
        if not time_k and strong and all(_in(r[0], _DEG) for r in strong.values()):
            n0 = next(iter(strong))
            findings.append(Finding("deg", f"{n0} is {strong[n0][0]:.1f} x the attitude's rate: body rates in deg/s?",
                                    " ".join(f"--scale {n}=pi/180" for n in ("wx", "wy", "wz"))))
            mism = True
        elif not time_k:
            sign = {n: (1 if _in(r[0], OK_SLOPE) else -1 if r[1] < 0 and _in(-r[0], _SIGN_SLOPE) else 0)
                    for n, r in strong.items()}
            neg = sorted(n for n, s_ in sign.items() if s_ < 0)
            if neg == ["wy", "wz"] or (neg == ["wy"] and "wz" not in strong):
                frd = mism = True
            elif neg == ["wz"] and sign.get("wx", 0) >= 0 and sign.get("wy", 0) >= 0:
                yaw_neg = mism = True
            elif neg:
                findings.append(Finding("sign", f"{', '.join(neg)} {'is' if len(neg) == 1 else 'are'} -1 x the "
                                        f"attitude's rate{'s' if len(neg) > 1 else ''}: signs reversed",
                                        " ".join(f"--scale {n}=-1" for n in neg)))
                mism = True
        if not strong:
            checks.append(Check("body rates vs attitude", "skipped", f"too little rotation to judge ({detail})",
                                ra["numbers"]))
        else:
            checks.append(Check("body rates vs attitude", "mismatch" if mism or time_k else "ok", detail, ra["numbers"]))
    # 4. gravity
    skip, gr = _gravity(flight)
    acc_frd = False
    if skip:
        checks.append(skip)
    else:
        az, norm = gr["az"], gr["norm"]
        if az <= -5.0 and 5.0 <= norm <= 15.0:
            acc_frd = True
            checks.append(Check("gravity in the accelerometer", "mismatch", f"median az {az:.2f} m/s²", {"az": az}))
        elif 0.8 <= norm <= 1.25 and abs(az) >= 0.5:
            findings.append(Finding("gravity", f"the accelerometer reads {norm:.2f} at rest: accelerations in g?",
                                    " ".join(f"--scale {n}=9.81" for n in ("ax", "ay", "az"))))
            checks.append(Check("gravity in the accelerometer", "mismatch", f"|a| {norm:.2f}", {"az": az}))
        else:
            checks.append(Check("gravity in the accelerometer", "ok", f"median az {az:.2f} m/s², |a| {norm:.2f}",
                                {"az": az, "norm": norm}))
    if frd:
        if acc_frd or not flight.has("az"):
            findings.append(Finding("frd", "wy and wz turn against the attitude (wx with it): body rates"
                                    + (" and accelerations" if acc_frd else "") + " in FRD (z down)",
                                    "--body-frame frd"))
        else:
            findings.append(Finding("frd", "wy and wz turn against the attitude (wx with it) while the "
                                    "accelerometer is FLU: body rates in FRD", "--scale wy=-1 --scale wz=-1"))
    elif acc_frd:
        findings.append(Finding("frd", f"az reads {gr['az']:.2f} m/s² (-g) at rest: accelerations in FRD (z down)",
                                "--scale ay=-1 --scale az=-1"))
    # 5. horizontal: swaps, yaw
    swap = yaw_alt = False
    if skip_hz:
        checks.append(skip_hz)
    else:
        s = hz["scores"]
        best = max((k_ for k_ in s if k_ != "as read"), key=lambda k_: s[k_] if math.isfinite(s[k_]) else -2)
        detail = ", ".join(f"{k_} {v:.2f}" for k_, v in s.items())
        if s[best] >= ALT_SCORE and s[best] - s["as read"] >= ALT_MARGIN and not time_k:
            swap, yaw_alt = best == "x/y swapped", best == "yaw negated"
            checks.append(Check("horizontal acceleration vs thrust axis", "mismatch", detail, hz["numbers"]))
        else:
            checks.append(Check("horizontal acceleration vs thrust axis",
                                "ok" if s["as read"] >= ALT_SCORE else "skipped",
                                detail if s["as read"] >= ALT_SCORE else
                                f"the acceleration does not follow the tilt any way ({detail})", hz["numbers"]))
    # 6. vertical
    skip, vt = _vertical(flight, acc_frd)
    z_down = False
    if skip:
        checks.append(skip)
    else:
        c = vt["corr"]
        z_down = math.isfinite(c) and c <= -VERTICAL_CORR and not time_k
        checks.append(Check("vertical acceleration vs thrust", "mismatch" if z_down else
                            "ok" if c >= VERTICAL_CORR else "skipped",
                            f"{vt['src']} against d(vz)/dt: r {c:.2f}"
                            + ("" if abs(c) >= VERTICAL_CORR else " (too weak to judge)"), vt["numbers"]))
    if z_down and (swap or not _horizontal_ok(checks)):
        findings.append(Finding("ned", "vz falls when the thrust rises" + (" and x/y are swapped" if swap else "")
                                + ": the data read as NED (z down)", "--world-frame ned"))
    elif z_down:
        findings.append(Finding("sign", "vz falls when the thrust rises: z points down",
                                "--scale z=-1 --scale vz=-1"))
    elif swap:
        findings.append(Finding("swap", f"the acceleration follows the tilt with x and y swapped (score "
                                f"{hz['scores']['x/y swapped']:.2f} vs {hz['scores']['as read']:.2f} as read): "
                                f"x and y swapped", _column_swap_fix(flight)))
    if yaw_neg or yaw_alt:
        why = ("wz turns against the attitude's yaw (wx, wy with it)" if yaw_neg else
               f"the acceleration follows the tilt with yaw negated (score {hz['scores']['yaw negated']:.2f} vs "
               f"{hz['scores']['as read']:.2f} as read)")
        findings.append(Finding("yaw", f"{why}: yaw negated (clockwise)?",
                                "--scale yaw=-1" + ("; if yaw is right: --scale wz=-1" if yaw_neg and not yaw_alt else "")))


def _horizontal_ok(checks) -> bool:
    return any(c.name.startswith("horizontal") and c.status == "ok" for c in checks)


def check_flights(flights: Sequence[Flight]) -> tuple[Consistency, ...]:
    """:func:`check_flight` of every flight."""
    return tuple(check_flight(f) for f in flights)


def raise_if_inconsistent(flights: Sequence[Flight], role: str = "") -> tuple[Consistency, ...]:
    """Raise :class:`ConventionError` (one line per finding, naming the file and the fix) when
    any flight's redundant signals disagree; else return the checks. ``role`` ("training",
    "test") names the flights in the message."""
    out = check_flights(flights)
    lines = [ln for c in out for ln in c.lines()]
    if lines:
        raise ConventionError(lines, role)
    return out

