"""The thrust curve of a command-driven vehicle, chosen from the TRAINING flights.

A vehicle that logs motor commands (or one throttle), not rotor speeds, makes thrust through a
curve the log does not state: ArduPilot's MOT_THST_EXPO form ``f_e(u) = (1 − e) u + e u²`` on the
normalised command u (:func:`priors.thrust.thrust_curve`). Its two pieces, Σu and Σu², are
collinear on any flight near hover (variance inflation 146-1270 on the real logs), so fitting
both scales is not identifiable and holding both at a nominal value nobody measured is no
model. Reduced to what the data identify: ONE shape parameter e and one linear thrust scale.

:func:`choose_thrust_curve` profiles e over [0, 1] on v̇z (where the thrust's magnitude shows):
at every e the linear scale and the vertical drag are refit (robust weights of a Huber fit,
bounded >= 0, no free constant: free fall at zero thrust), e is the minimum of the residual sum
of squares (between grid points: the parabola through the grid minimum), and its 95 % interval
:func:`droneid.core.regression.bootstrap_span` of the minima over a block bootstrap of (flight,
time block) units (each replicate re-profiles e). A flat profile gives a wide interval: the
output says so and never pretends a shape. The thrust is the rotors'
(:mod:`droneid.fitting.command_thrust`): each rotor's speed through a first-order motor lag τ
profiled beside e (kept by the block test), thrust ∝ Σ speed², compared with the target as the
mean over the differentiator's window, and through the least-squares slope the logged velocity
may itself be (:func:`_over_smoothings`: the intervals span every slope the data admit).

Battery compensation: the motors see the battery's voltage, so the thrust of a command falls as
it sags; ArduPilot scales its commands by V/V_ref to make up for it. The candidate reads every
command as u·V/V_ref (V_ref: the log's :data:`V_REF_NAMES` when declared, else the training
flights' largest screened voltage) and is kept only when :func:`droneid.fitting.decide.decide` on held-out
v̇z residuals over the (flight, block) units says it helps (α = :data:`VOLTAGE_ALPHA`); the
voltage's own glitches are screened like every input (:mod:`droneid.logs.screening`).

Where a log declares MOT_THST_EXPO / MOT_THST_HOVER (ArduPilot PARM), the identified value is
shown beside the declared one (:attr:`ThrustCurve.declared`); the declared values never decide.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from priors.thrust import COMMAND_SOURCES

from droneid.logs.flight import VEHICLE_PARAMETERS
from droneid.fitting.decide import decide
from droneid.errors import ConfigError
from droneid.core.differentiation import averaging_window
from droneid.core.regression import blocked_cv, bootstrap_span, gram, gram_bounded_lstsq, held_factor, huber_factor, robust_fit
from droneid.fitting.command_thrust import FINE_STEPS, CommandThrust, LinearThrust, lagged, window_rows
from droneid.fitting.terms import prior_terms, split_terms
from droneid.dataset.validation import time_blocks

__all__ = ["ThrustCurve", "choose_thrust_curve", "normalised", "over_offsets", "lagged", "LAG_GRID_S", "profile_expo", "EXPO_GRID", "VOLTAGE_ALPHA",
           "declared_parameters", "N_BOOT_EXPO"]

#: the shapes e profiled (ArduPilot allows MOT_THST_EXPO in [-1, 1]; a propeller's is 0.3-0.8)
EXPO_GRID = tuple(round(0.02 * k, 2) for k in range(51))
#: family-wise level of the battery-compensation decision
VOLTAGE_ALPHA = 0.01
#: family-wise level of the motor-lag decision
LAG_ALPHA = 0.01
#: block-bootstrap replicates of the expo's interval
N_BOOT_EXPO = 200
#: ArduPilot parameters that declare the thrust curve or the command normalisation (one home)
DECLARED = VEHICLE_PARAMETERS
#: the compensation's V_ref by name: MOT_BAT_VOLT_MAX, before ArduCopter 3.6 MOT_THST_BAT_MAX
V_REF_NAMES = ("MOT_BAT_VOLT_MAX", "MOT_THST_BAT_MAX")
_TARGET = "vz_dot"


@dataclass(frozen=True)
class ThrustCurve:
    """The thrust curve identified from the training flights.

    source : the prior's command source (``motor`` or ``throttle``)
    expo, interval : the shape e of (1 − e)u + e u² and its 95 % block-bootstrap interval
    profile : {e: residual sum of squares relative to the best e} on v̇z (the grid)
    hover, hover_interval : the thrust fraction that holds the vehicle at hover, g / (N k) for N
        motors of k m/s² at full command (ArduPilot's MOT_THST_HOVER), and its 95 % interval
    voltage : battery compensation u·V/V_ref kept (the block test said it helps)
    v_ref : V_ref (V) of the candidate (None without a battery voltage); v_ref_from : where from
    decision : the block test of the battery compensation (:class:`droneid.fitting.decide.Decision`), or
        None when it could not be tried; why_not : why it was not tried ("" when it was)
    declared : {ArduPilot parameter: value} the logs declare (:data:`DECLARED`)
    n_units : the (flight, block) units the interval was drawn over
    free_expo : the shape of the free fit b1·Σu + b2·Σu² (e = b2/(b1 + b2)); outside [0, 1]
        when the data pull the shape out of its physical range (:attr:`at_bound`)
    offsets_s : (low, high) the input offsets the interval covers (:func:`over_offsets`: the
        offsets the chosen one does not beat); () for the commands read without offset only
    lag_s, lag_interval : the first-order motor lag (s) the shape was profiled with and its 95 %
        interval (0: none kept); lag_decision : the block test of the best lag ``lag_tried_s``
        against none (None: the best lag was none, or not testable)
    smoothing_s, smoothings_s : the half-width h (s) of the least-squares slope the logged
        velocity is taken to be (0: the velocity as it is; a logged velocity is itself smoothed
        by its estimator) and the (low, high) half-widths the chosen one does not beat, which every
        interval here spans (:func:`_over_smoothings`); smoothing_decision : the block test of the
        best half-width against none (None: not testable)
    """
    source: str
    expo: float
    interval: tuple
    profile: Mapping[float, float]
    hover: float
    hover_interval: tuple
    voltage: bool = False
    v_ref: float | None = None
    v_ref_from: str = ""
    decision: object | None = None
    why_not: str = ""
    declared: Mapping[str, float] = field(default_factory=dict)
    n_units: int = 0
    free_expo: float = math.nan
    offsets_s: tuple = ()
    lag_s: float = 0.0
    lag_interval: tuple = (0.0, 0.0)
    lag_decision: object | None = None
    lag_tried_s: float = 0.0
    smoothing_s: float = 0.0
    smoothings_s: tuple = (0.0, 0.0)
    smoothing_decision: object | None = None

    @property
    def at_bound(self) -> bool:
        """Whether the data pull the shape outside [0, 1] (e sits on its bound)."""
        return not 0.0 <= self.free_expo <= 1.0

    @property
    def identified(self) -> bool:
        """Whether the data pin the shape down: its interval is narrower than half of [0, 1]."""
        return self.interval[1] - self.interval[0] < 0.5

    def text(self) -> str:
        """One line for identify's output."""
        lo, hi = self.interval
        what = "motor commands" if self.source == "motor" else "the throttle"
        norm = ""
        if {"MOT_SPIN_MIN", "MOT_SPIN_MAX"} <= set(self.declared) and self.source == "motor":
            norm = (f" with u = (command − {self.declared['MOT_SPIN_MIN']:g})/"
                    f"({self.declared['MOT_SPIN_MAX']:g} − {self.declared['MOT_SPIN_MIN']:g}) "
                    f"(the log's MOT_SPIN_MIN/MAX)")
        over = (f", and over the offsets {1000 * self.offsets_s[0]:+.0f} to {1000 * self.offsets_s[1]:+.0f} ms "
                f"the offset's interval admits" if self.offsets_s else "")
        shape = (f"thrust curve of {what}: (1 − e)·u + e·u²{norm}, e = {_expo_text(self.expo, lo, hi)} "
                 f"(95 %, block bootstrap over {self.n_units} (flight, block) units{over}; v̇z profiled with "
                 f"the thrust scale and drag refit at each e)")
        if self.at_bound:
            pull = (f"to {self.free_expo:.2f}" if math.isfinite(self.free_expo) else
                    "below 0" if self.expo == 0 else "above 1")
            shape += (f"; e sits on its bound {self.expo:g}: the data pull it {pull}, outside [0, 1] (the "
                      f"command map lacks something, e.g. a command normalisation other than the one read)")
        elif not self.identified:
            shape += "; the flights hardly constrain the shape (a flat profile): e is a best guess"
        if self.lag_decision is not None:
            lo_l, hi_l = self.lag_interval
            shape += (f"; motor lag (first order on each rotor's speed) "
                      f"{1000 * (self.lag_s or self.lag_tried_s):.0f} ms "
                      + (f"[{1000 * lo_l:.0f}, {1000 * hi_l:.0f}] ms kept (e profiled with it; the one-step v̇ models "
                         f"read the commands at the plan's offset, the open loop and the exported vehicle at t "
                         f"through this lag: each describes how the commands lead their thrust, never both at once)"
                         if self.lag_s else "not kept") + f" (decided with the velocity as logged): {self.lag_decision.evidence}")
        if self.smoothing_decision is not None:
            lo_s, hi_s = (1000 * v for v in self.smoothings_s)
            shape += (f"; the logged velocity read "
                      + (f"as a least-squares slope over ±{1000 * self.smoothing_s:.0f} ms" if self.smoothing_s
                         else "as it is")
                      + f" (a logged velocity is smoothed by its estimator: slopes over ±{lo_s:.0f} to ±{hi_s:.0f} ms "
                      f"admitted, the intervals span them; the best: {self.smoothing_decision.evidence})")
        hv = (f"; hover thrust fraction {self.hover:.3f} [{self.hover_interval[0]:.3f}, "
              f"{self.hover_interval[1]:.3f}]")
        dec = ""
        parts = []
        if "MOT_THST_EXPO" in self.declared:
            parts.append(f"MOT_THST_EXPO {self.declared['MOT_THST_EXPO']:g} (identified {self.expo:.2f})")
        if "MOT_THST_HOVER" in self.declared:
            parts.append(f"MOT_THST_HOVER {self.declared['MOT_THST_HOVER']:.3g} (identified {self.hover:.3f})")
        elif "THR_MID" in self.declared:     # ArduCopter before 3.5: the hover throttle, 0-1000
            parts.append(f"THR_MID {self.declared['THR_MID']:g} (the hover throttle of ArduCopter before 3.5: "
                         f"{self.declared['THR_MID'] / 1000:.3g} of full; identified {self.hover:.3f})")
        if parts:
            dec = "; the log declares " + ", ".join(parts)
        if self.decision is not None:
            batt = (f"; battery compensation u·V/{self.v_ref:.4g} V ({self.v_ref_from}) "
                    f"{'kept' if self.voltage else 'not kept'}: {self.decision.evidence}")
        else:
            batt = f"; battery compensation not tried: {self.why_not}"
        return shape + hv + dec + batt

    def verdict(self) -> str:
        """What a verdict of a target driven by these commands can say about the thrust curve."""
        lo, hi = self.interval
        dec = self.declared.get("MOT_THST_EXPO")
        beside = f" (the log declares MOT_THST_EXPO {dec:g})" if dec is not None else ""
        batt = "with" if self.voltage else "without"
        if self.at_bound:
            return (f"Its thrust curve sits on its bound e = {self.expo:g}{beside}: the data want a shape "
                    f"outside [0, 1], so the command map lacks something and the thrust scale absorbs it.")
        if not self.identified:
            return (f"The flights hardly constrain its thrust curve (e = {_expo_text(self.expo, lo, hi)}"
                    f"{beside}): trust it only for commands like the training flights'.")
        return (f"Thrust from the commands through the identified curve e = {_expo_text(self.expo, lo, hi)}"
                f"{beside}, {batt} battery compensation.")

    def to_dict(self) -> dict:
        return {"source": self.source, "expo": self.expo, "interval": list(self.interval),
                "identified": self.identified, "hover": self.hover, "hover_interval": list(self.hover_interval),
                "voltage": self.voltage, "v_ref": self.v_ref, "v_ref_from": self.v_ref_from,
                "voltage_decision": self.decision.to_dict() if self.decision is not None else None,
                "voltage_not_tried": self.why_not, "declared": dict(self.declared),
                "n_units": self.n_units, "offsets_s": list(self.offsets_s), "lag_s": self.lag_s,
                "lag_interval": list(self.lag_interval), "lag_tried_s": self.lag_tried_s,
                "lag_decision": self.lag_decision.to_dict() if self.lag_decision is not None else None,
                "smoothing_s": self.smoothing_s, "smoothings_s": list(self.smoothings_s),
                "smoothing_decision": self.smoothing_decision.to_dict() if self.smoothing_decision is not None else None,
                "free_expo": self.free_expo, "at_bound": self.at_bound, "profile": {f"{e:.2f}": v for e, v in self.profile.items()}}


def _expo_text(e: float, lo: float, hi: float) -> str:
    """``e [lo, hi]`` with 3 decimals where the interval is narrower than 0.02, else 2."""
    d = 3 if hi - lo < 0.02 else 2
    return f"{e:.{d}f} [{lo:.{d}f}, {hi:.{d}f}]"


def declared_parameters(flights) -> dict:
    """{ArduPilot parameter: value} of :data:`DECLARED` that the flights' logs declare
    (``Provenance.parameters``); a parameter the flights declare differently is left out."""
    seen: dict[str, set] = {}
    for f in flights:
        for k, v in dict(getattr(f.provenance, "parameters", ()) or ()).items():
            if k in DECLARED:
                seen.setdefault(k, set()).add(float(v))
    return {k: next(iter(v)) for k, v in seen.items() if len(v) == 1}


def normalised(prior, flights):
    """The command prior with the command normalisation the flights' logs declare: the motor
    commands' curve runs from MOT_SPIN_MIN to MOT_SPIN_MAX (ArduPilot; the PWM range MOT_PWM_MIN/MAX
    is applied by the reader); unchanged for another prior or where nothing is declared."""
    if prior.params.get("source") != "motor":
        return prior
    d = declared_parameters(flights)
    lo, hi = d.get("MOT_SPIN_MIN"), d.get("MOT_SPIN_MAX")
    if lo is None or hi is None or not 0.0 <= lo < hi <= 1.0:
        return prior
    return prior.with_params(spin_min=float(lo), spin_max=float(hi))


_LO, _HI = np.zeros(2), np.full(2, np.inf)

#: first-order motor lags τ (s) profiled beside the shape (0: none)
LAG_GRID_S = tuple(round(0.01 * k, 3) for k in range(11))
#: half-widths h (s) of the least-squares slope the logged velocity may be (0: the velocity as
#: it is): a logged velocity is itself an estimate (a motion-capture slope over several frames, a
#: Savitzky-Golay derivative, an EKF), so its difference averages the acceleration over more than
#: the differentiator's window, by an amount no log states, and a shape that curves the thrust is
#: biased by it (:func:`_over_smoothings`; :func:`droneid.fitting.command_thrust.slope_smoothed`)
SMOOTHING_GRID_S = (0.0, 0.025, 0.05, 0.075, 0.1)
#: family-wise level of choosing a smoothing other than none (Holm over the grid), and the level
#: of the smoothings the chosen one does not beat (the interval's, as the offsets')
SMOOTHING_ALPHA, SMOOTHING_INTERVAL_ALPHA = 0.01, 0.05
#: half-width of the shapes e each slope is profiled over, about the velocity-as-it-is minimum
LOCAL_EXPO = 0.1


def _nnls2(a, b, p, c, q, r):
    """(RSS, x, z) of the least squares ``y ≈ x·F + z·D`` with x, z >= 0 from its sufficient
    statistics (a = F'F, b = F'D, p = F'y, c = D'D, q = D'y, r = y'y, broadcast arrays): the
    best feasible of the free solution, each column alone and none (the KKT points of a convex
    problem on the quadrant), solved in closed form for every entry at once."""
    a, b, p, c, q, r = np.broadcast_arrays(*(np.asarray(v, float) for v in (a, b, p, c, q, r)))
    det = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        free_ok = (a > 0) & (c > 0) & (det > 1e-12 * a * c)
        cands = [(np.where(free_ok, (c * p - b * q) / det, np.nan), np.where(free_ok, (a * q - b * p) / det, np.nan)),
                 (np.where(a > 0, np.maximum(p / a, 0.0), 0.0), np.zeros_like(a)),
                 (np.zeros_like(a), np.where(c > 0, np.maximum(q / c, 0.0), 0.0)),
                 (np.zeros_like(a), np.zeros_like(a))]
    best, bx, bz = np.full(a.shape, np.inf), np.zeros(a.shape), np.zeros(a.shape)
    for x, z in cands:
        rss = r - 2.0 * (x * p + z * q) + x * x * a + 2.0 * x * z * b + z * z * c
        better = (x >= 0) & (z >= 0) & np.isfinite(rss) & (rss < best)
        best, bx, bz = np.where(better, rss, best), np.where(better, x, bx), np.where(better, z, bz)
    return best, bx, bz


def _vertex(x: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x at the minimum, the minimum, index of the grid minimum) of each profile ``Y`` (..., n)
    on the grid ``x`` (n,): the parabola through the grid minimum and its two neighbours (the
    grid point itself at an end of the grid or where the parabola does not curve up)."""
    Y = np.where(np.isfinite(Y), Y, np.inf)
    i = np.argmin(Y, axis=-1)
    n = x.size
    xm, ym = x[i], np.take_along_axis(Y, i[..., None], -1)[..., 0]
    if n < 3:
        return xm, ym, i
    j = np.clip(i, 1, n - 2)
    x0, x1, x2 = x[j - 1], x[j], x[j + 1]
    y0, y1, y2 = (np.take_along_axis(Y, (j + d)[..., None], -1)[..., 0] for d in (-1, 0, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        d01, d12 = (y1 - y0) / (x1 - x0), (y2 - y1) / (x2 - x1)
        curv = (d12 - d01) / (x2 - x0)                       # half the second derivative
        xv = 0.5 * (x0 + x1) - d01 / (2.0 * curv)
        yv = y0 + d01 * (xv - x0) + curv * (xv - x0) * (xv - x1)
    inner = (i == j) & np.isfinite(xv) & (curv > 0) & np.all(np.isfinite([y0, y1, y2]), axis=0)
    xv = np.clip(xv, x0, x2)
    return np.where(inner, xv, xm), np.where(inner, np.minimum(yv, ym), ym), i


def _surface_min(taus: np.ndarray, grid: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(τ, e) at the minimum of each RSS surface ``R`` (..., T, E) over the lag grid ``taus`` and
    the shape grid ``grid``: e's minimum at every τ (:func:`_vertex`), τ's over those minima, and e
    interpolated at τ between its neighbouring lags (e moves with τ)."""
    e_at, r_at, _ = _vertex(grid, R)                          # (..., T)
    tau, _, k = _vertex(taus, r_at)
    if taus.size < 2:
        return tau, e_at[..., 0]
    lo = np.clip(np.searchsorted(taus, tau, side="right") - 1, 0, taus.size - 2)
    w = np.clip((tau - taus[lo]) / (taus[lo + 1] - taus[lo]), 0.0, 1.0)
    e_lo = np.take_along_axis(e_at, lo[..., None], -1)[..., 0]
    e_hi = np.take_along_axis(e_at, (lo + 1)[..., None], -1)[..., 0]
    return tau, e_lo + w * (e_hi - e_lo)


def profile_expo(thrust, drag: np.ndarray, y: np.ndarray, units: np.ndarray, *,
                 grid: Sequence[float] = EXPO_GRID, n_boot: int = N_BOOT_EXPO, seed: int = 0,
                 lags: Sequence[float] = (0.0,)) -> dict:
    """The profile of the shape e (and the motor lag τ) of ``y ≈ a·thrust(e, τ) + d·drag`` (a, d
    >= 0 refit at every grid point; ``y`` the target less its known physics, m/s²; ``thrust`` a
    callable of (shapes, τ) giving the thrust column of each shape on the rows, m/s²:
    :class:`~droneid.fitting.command_thrust.CommandThrust` or
    :class:`~droneid.fitting.command_thrust.LinearThrust`; ``drag`` the drag term on the rows), with
    the robust (Huber) weights of the fit at the least-squares best (τ, e): weights from a wrong
    shape or lag would depend on the noise where it misfits. ``units``: (flight, block) ids of
    the rows; ``lags``: the τ (s) profiled (:data:`LAG_GRID_S`; (0,): none).

    Returns {"expo", "free_expo" (the shape of the free fit of the thrust at e = 0 and e = 1 at the
    chosen lag, e = b2/(b1 + b2); outside [0, 1] when the data pull e out of its range), "interval"
    (95 %), "scale" (a at e), "scale_interval", "profile" {e: RSS / min RSS at the chosen lag},
    "n_units", "lag_s", "lag_interval", "thrust" (the thrust column at the chosen (τ, e))}: (τ, e)
    from the least residual sum of squares (:func:`_surface_min`: between grid points where the
    profile curves); over ``n_boot`` block-bootstrap replicates of the units (each re-profiled over the whole grid,
    the weights held: spreads about e, τ and the scales' median times Huber's factor, regression.huber_factor),
    e's and τ's intervals :func:`~droneid.core.regression.bootstrap_span` of their minima, the scale's the
    percentiles of the scales at the replicates' grid minima."""
    grid, taus = np.asarray(grid, float), np.asarray(lags, float)
    drag, y, units = np.asarray(drag, float), np.asarray(y, float), np.asarray(units)
    cols = [np.asarray(thrust(grid, float(tau)), float) for tau in taus]     # T x (rows, E)
    ok = np.isfinite(y) & np.isfinite(drag) & np.all([np.all(np.isfinite(F), axis=1) for F in cols], axis=0)
    ids, inv = np.unique(units, return_inverse=True)
    M = np.zeros((ids.size, y.size))
    M[inv, np.arange(y.size)] = 1.0

    def stats(w):
        """Per-unit sufficient statistics (U, T, E) and (U, 1, 1) with row weights ``w``."""
        w = np.where(ok, w, 0.0)
        Fw = [np.where(ok[:, None], F, 0.0) for F in cols]
        dz, yz = np.where(ok, drag, 0.0), np.where(ok, y, 0.0)
        a = np.stack([M @ (w[:, None] * F * F) for F in Fw], axis=1)
        b = np.stack([M @ (w[:, None] * F * dz[:, None]) for F in Fw], axis=1)
        p = np.stack([M @ (w[:, None] * F * yz[:, None]) for F in Fw], axis=1)
        c, q, r = ((M @ (w * v))[:, None, None] for v in (dz * dz, dz * yz, yz * yz))
        return a, b, p, c, q, r

    plain = [s.sum(axis=0) for s in stats(np.ones(y.size))]
    tau0, e0 = (float(v) for v in _surface_min(taus, grid, _nnls2(*plain)[0]))
    F0 = np.asarray(thrust(np.array([e0]), tau0), float)[:, 0]
    A0 = np.column_stack([F0, drag])
    good = ok & np.isfinite(F0)
    weights = np.zeros(y.size)
    weights[good] = (fit0 := robust_fit(A0[good], y[good], _LO, _HI)).weights
    unit_stats = stats(weights)
    R, _, _ = _nnls2(*(s.sum(axis=0) for s in unit_stats))
    tau_hat, e = (float(v) for v in _surface_min(taus, grid, R))
    F = np.asarray(thrust(np.array([0.0, 1.0, e]), tau_hat), float)
    Fe = F[:, 2]
    fin = ok & np.all(np.isfinite(F), axis=1)
    wsq = np.sqrt(weights[fin])
    a_hat = float(gram_bounded_lstsq(gram(np.column_stack([Fe, drag])[fin], y[fin], weights[fin]), _LO, _HI)[0])
    bf = np.linalg.lstsq(np.column_stack([F[fin, 0], F[fin, 1], drag[fin]]) * wsq[:, None], y[fin] * wsq, rcond=None)[0]
    free_e = float(bf[1] / (bf[0] + bf[1])) if bf[0] + bf[1] > 0 else math.nan
    # every replicate at every (τ, e) solved together: replicate i's unit counts drawn replicate
    # by replicate, as one at a time would
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, ids.size, (n_boot, ids.size))
    counts = np.stack([np.bincount(d, minlength=ids.size) for d in draws]).astype(float)
    boot = [np.tensordot(counts, s, axes=(1, 0)) for s in unit_stats]     # (B, T, E) / (B, 1, 1)
    Rb, xb, _ = _nnls2(*boot)
    lags_b, es = _surface_min(taus, grid, Rb)
    kb = np.argmin(np.where(np.isfinite(Rb), Rb, np.inf).reshape(n_boot, -1), axis=1)
    scales = xb.reshape(n_boot, -1)[np.arange(n_boot), kb]
    es, lags_b, scales = (held_factor(v, c, huber_factor(fit0), 0.0) for v, c in ((es, e), (lags_b, tau_hat), (scales, np.median(scales))))
    lo, hi = bootstrap_span(es, e, min(grid[0], EXPO_GRID[0]), max(grid[-1], EXPO_GRID[-1]))
    # the replicates' scales are at their grid minimum, a_hat at the refined (τ, e): not one estimator
    # to reflect about, so the scale keeps the percentile interval
    slo, shi = np.percentile(scales, [2.5, 97.5])
    k = int(np.argmin(np.abs(taus - tau_hat)))
    best = float(np.min(R[k])) if np.min(R[k]) > 0 else 1.0
    return {"expo": e, "free_expo": free_e, "interval": (float(lo), float(hi)), "scale": a_hat,
            "scale_interval": (float(slo), float(shi)),
            "profile": {float(g): float(v / best) for g, v in zip(grid, R[k])}, "n_units": int(ids.size),
            "lag_s": tau_hat, "lag_interval": bootstrap_span(lags_b, tau_hat, taus[0], taus[-1]),
            "thrust": Fe}


def _rows(flights, cfg, delays, inputs, cuts):
    """(the v̇z dataset on the grid of Ts, the same inputs on a grid :data:`FINE_STEPS` times finer):
    the training rows before ``cuts`` whose target is the mean of the acceleration over its
    window (:func:`~droneid.fitting.command_thrust.window_rows`: not the one-sided differences at
    a segment's ends), the thrust inputs read at ``delays``."""
    from droneid.planning.plan import dataset_builder, train_rows
    from droneid.dataset.builder import DatasetBuilder

    ds = train_rows(dataset_builder(cfg, delays).build(list(flights), target=_TARGET, inputs=inputs), cuts)
    # after the cut: the fine rows end there too, so the last row before it has no whole window
    ds = ds.subset(window_rows(ds.t, ds.flight, averaging_window(cfg.method, cfg.ts)))
    fine = DatasetBuilder(ts=cfg.ts / FINE_STEPS, method=cfg.method, delays_s=dict(delays or {}))
    return ds, train_rows(fine.build(list(flights), target=_TARGET, inputs=inputs), cuts)


def _columns(prior, ds, fine, cfg, smoothing_s: float = 0.0):
    """(thrust: :class:`CommandThrust` of the command prior ``prior`` (its normalisation and v_ref
    as given) on the rows of ``ds`` from the finer rows ``fine``, the logged velocity taken as a
    least-squares slope over ±``smoothing_s`` s (0: as it is), the drag column, y less the known
    physics) of v̇z."""
    feats = split_terms(prior, _TARGET)
    role = lambda r: [i for i, f in enumerate(feats) if f.role == r]    # noqa: E731
    A, yy, _, _ = prior_terms(prior, _TARGET)._problem(ds.columns(), ds.y)
    p = prior.params
    names = ([f"motor{i}" for i in range(1, int(p.get("motors", 1)) + 1)] if p.get("source") == "motor"
             else ["throttle"])
    lo, hi = float(p.get("spin_min", 0.0)), float(p.get("spin_max", 1.0))
    fc = fine.columns()
    scale = (np.asarray(fc["battery_voltage"], float) / p["v_ref"])[:, None] if p.get("v_ref") else 1.0
    q = np.column_stack([(np.asarray(fc[n], float) - lo) / (hi - lo) for n in names]) * scale
    full = dict(fc, **{n: np.full(len(fine), hi) for n in names})   # one rotor's full thrust: k_T·b_z
    if p.get("v_ref"):
        full["battery_voltage"] = np.full(len(fine), float(p["v_ref"]))
    Af, _, _, _ = prior_terms(prior.with_params(expo=1.0), _TARGET)._problem(full, fine.y)
    k = Af[:, role("thrust")].sum(axis=1) / len(names)
    thrust = CommandThrust.build(q, k, fine.t, fine.flight, ds.t, ds.flight, averaging_window(cfg.method, cfg.ts),
                                 smoothing_s)
    return thrust, A[:, role("drag")].sum(axis=1), yy


def _over_smoothings(prof: dict, prior, ds, fine, cfg, blocks, lags: Sequence[float], *, seed: int = 0) -> tuple[dict, dict]:
    """(the profile at the chosen smoothing, with its intervals widened to the hull of the
    intervals at every smoothing the chosen one does not beat; {"smoothing_s", "admitted_s" (low,
    high), "decision"}). ``prof``: :func:`profile_expo` with the thrust compared through the
    differentiator's own window (``lags`` as it was profiled with, ``prior`` its command prior).

    Each slope half-width of :data:`SMOOTHING_GRID_S` is profiled the same way and scored by its
    held-out v̇z residuals over the (flight, block) units ``blocks`` (the thrust at its own (τ, e),
    scale and drag refit per held-out block); the widths ≠ 0 are tested against none by the rule
    of :mod:`droneid.fitting.decide` (Holm over the grid at :data:`SMOOTHING_ALPHA`), the lowest
    held-out error among the accepted is chosen, and every width it does not beat at
    :data:`SMOOTHING_INTERVAL_ALPHA` is admitted: a condition of how the log estimated its velocity,
    which the shape's, the lag's and the scale's intervals span like the offsets the data admit."""
    from droneid.fitting.decide import decide_family

    none = {"smoothing_s": 0.0, "admitted_s": (0.0, 0.0), "decision": None}
    # a slope of fewer than two fine steps is the velocity as it is (slope_smoothed)
    widths = [w for w in SMOOTHING_GRID_S[1:] if w >= 2 * cfg.ts / FINE_STEPS]
    if not widths:
        return prof, none
    thrust0, D, yy = _columns(prior, ds, fine, cfg)
    # a slope moves e by hundredths: each is profiled on the shapes near the velocity-as-it-is
    # minimum (e ± LOCAL_EXPO; every lag: τ can move further), a fifth of the cost; profiled on
    # the whole grid again where that matters (below)
    near = [g for g in EXPO_GRID if abs(g - prof["expo"]) <= LOCAL_EXPO + 1e-9]
    local = near if len(near) >= 3 else list(EXPO_GRID)

    def profiled(w, grid):
        return profile_expo(replace(thrust0, slope_s=w), D, yy, blocks, seed=seed, lags=lags, grid=grid)

    profs = {0.0: prof, **{w: profiled(w, local) for w in widths}}
    errs = {w: yy - blocked_cv(np.column_stack([p["thrust"], D]), yy, blocks, _LO, _HI) for w, p in profs.items()}
    names = {f"velocity a slope over ±{1000 * w:.0f} ms": w for w in widths}
    try:
        fam = decide_family(errs[0.0], {n: errs[w] for n, w in names.items()}, blocks, alpha=SMOOTHING_ALPHA)
    except ConfigError:     # fewer than 3 blocks: nothing testable, nothing spanned
        return prof, none
    shared = np.all([np.isfinite(e) for e in errs.values()], axis=0)
    rms = {w: float(np.sqrt(np.mean(e[shared] ** 2))) for w, e in errs.items()}
    accepted = [w for n, w in names.items() if fam[n].accepted]
    best = min(accepted, key=lambda w: (rms[w], w)) if accepted else 0.0
    decision = fam[next(n for n, w in names.items() if w == best)] if best else \
        fam[min(names, key=lambda n: (rms[names[n]], names[n]))]
    same = [w for w in profs if w == best or not decide(errs[w], errs[best], blocks, alpha=SMOOTHING_INTERVAL_ALPHA,
                                                        min_effect_pct=0.0).accepted]
    # the whole grid where the local one could have cut a profile short: the chosen width (its
    # profile is reported), and an admitted one whose estimate or interval reaches the local edge
    step = EXPO_GRID[1] - EXPO_GRID[0]

    def cut(p):
        ends = [v for v in (p["expo"], *p["interval"])]
        return ((local[0] > EXPO_GRID[0] and min(ends) <= local[0] + step) or
                (local[-1] < EXPO_GRID[-1] and max(ends) >= local[-1] - step))
    for w in same:
        if w and (w == best or cut(profs[w])):
            profs[w] = profiled(w, EXPO_GRID)
    out = dict(profs[best])
    for key in ("interval", "scale_interval", "lag_interval"):
        out[key] = (min(profs[w][key][0] for w in same), max(profs[w][key][1] for w in same))
    return out, {"smoothing_s": best, "admitted_s": (min(same), max(same)), "decision": decision}


def over_offsets(curve: ThrustCurve, train_flights, prior, cfg, cuts, signals: Sequence[str],
                 offsets: Sequence[float], *, seed: int = 0) -> ThrustCurve:
    """``curve`` (chosen with the commands read at one offset) with its interval widened to the
    hull of the intervals at every offset of ``offsets`` (the offsets the chosen one does not
    beat, :class:`droneid.planning.plan.OffsetDecision`): how the commands lead their thrust is itself
    uncertain (a motor lag is no pure offset), and the shape moves with it. ``prior``: the
    command prior with the curve's battery compensation."""
    lo, hi = curve.interval
    inputs = tuple(prior.inputs(_TARGET))
    slopes = sorted({float(curve.smoothing_s), *(float(v) for v in curve.smoothings_s)})
    for d in offsets:
        ds, fine = _rows(train_flights, cfg, {s: float(d) for s in signals}, inputs, cuts)
        if len(ds) < 30:
            continue
        blocks = time_blocks(ds.t, ds.flight, alpha=VOLTAGE_ALPHA)
        for h in slopes:        # the velocity's slopes the curve admits, at each offset
            prof = profile_expo(*_columns(prior, ds, fine, cfg, h), blocks, seed=seed)
            lo, hi = min(lo, prof["interval"][0]), max(hi, prof["interval"][1])
    return replace(curve, interval=(lo, hi), offsets_s=(min(offsets), max(offsets)) if len(offsets) else ())


def choose_thrust_curve(train_flights, prior, cfg, cuts=None, delays=None, *, seed: int = 0) -> ThrustCurve | None:
    """The thrust curve of a command prior (``prior.params["source"]`` in
    :data:`priors.thrust.COMMAND_SOURCES`) from the training rows of v̇z (``cuts``: hold-out
    starts, ``delays``: {signal: s} the thrust inputs are read at), with the battery
    compensation decided by the block test; None for another prior or without v̇z rows."""
    source = prior.params.get("source")
    if source not in COMMAND_SOURCES or _TARGET not in prior.targets:
        return None
    declared = declared_parameters(train_flights)
    base = prior.with_params(v_ref=None)
    have_v = all("battery_voltage" in f.signals for f in train_flights)
    v_ref, v_from, why_not = None, "", ""
    inputs = tuple(base.inputs(_TARGET))
    if have_v:
        inputs = tuple(dict.fromkeys(inputs + ("battery_voltage",)))
    ds, fine = _rows(train_flights, cfg, delays, inputs, cuts)
    if len(ds) < 30:
        return None
    blocks = time_blocks(ds.t, ds.flight, alpha=VOLTAGE_ALPHA)
    if have_v:
        volts = np.asarray(ds.columns()["battery_voltage"], float)
        named = next((n for n in V_REF_NAMES if declared.get(n, 0) > 0), None)
        if named is not None:
            v_ref, v_from = float(declared[named]), f"the log's {named}"
        elif volts.size and float(np.max(volts)) > 0:
            v_ref, v_from = float(np.round(np.max(volts), 2)), "the training flights' highest voltage"
        else:
            why_not = "no positive battery voltage on the training rows"
    else:
        why_not = "the training flights do not all log a battery voltage"
    prof = profile_expo(*_columns(base, ds, fine, cfg), blocks, seed=seed)
    decision, keep = None, False
    if v_ref is not None:
        cand = prior.with_params(v_ref=v_ref)
        prof_v = profile_expo(*_columns(cand, ds, fine, cfg), blocks, seed=seed)
        cols = ds.columns()
        err0 = ds.y - prior_terms(base.with_params(expo=prof["expo"]), _TARGET).cv_predictions(cols, ds.y, blocks)
        err1 = ds.y - prior_terms(cand.with_params(expo=prof_v["expo"]), _TARGET).cv_predictions(cols, ds.y, blocks)
        try:
            decision = decide(err0, err1, blocks, alpha=VOLTAGE_ALPHA, what="battery compensation")
        except ConfigError as exc:   # fewer than 3 blocks: not testable
            why_not = str(exc)
        keep = bool(decision is not None and decision.accepted)
        if keep:
            prof = prof_v
    # a first-order motor lag beside the shape: kept only when the block test says it helps
    thrust, D, yy = _columns(prior.with_params(v_ref=v_ref if keep else None), ds, fine, cfg)
    prof_lag = profile_expo(thrust, D, yy, blocks, seed=seed, lags=LAG_GRID_S)
    lag_decision = None
    if prof_lag["lag_s"] > 0:
        def held_out(p):
            return yy - blocked_cv(np.column_stack([p["thrust"], D]), yy, blocks, _LO, _HI)
        try:
            lag_decision = decide(held_out(prof), held_out(prof_lag), blocks, alpha=LAG_ALPHA,
                                  what=f"motor lag {1000 * prof_lag['lag_s']:.0f} ms")
        except ConfigError:
            lag_decision = None
        if lag_decision is not None and lag_decision.accepted:
            prof = prof_lag
    # the logged velocity as it is, or as the least-squares slope it may itself be (where the log smoothed it)
    prof, smooth = _over_smoothings(prof, prior.with_params(v_ref=v_ref if keep else None), ds, fine, cfg, blocks,
                                    LAG_GRID_S if prof is prof_lag else (0.0,), seed=seed)
    motors = int(prior.params.get("motors", 1)) if source == "motor" else 1
    g = float(prior.params.get("g", 9.81))
    k_nom = float(prior.params.get("k_T", 1.0))
    # the thrust at full command on every motor, m/s²: the fitted scale times the nominal k_T per
    # unit of f_e, times N
    full = lambda s: s * k_nom * motors   # noqa: E731
    hover, (slo, shi) = g / full(prof["scale"]) if prof["scale"] > 0 else math.nan, prof["scale_interval"]
    h_iv = (g / full(shi) if shi > 0 else math.nan, g / full(slo) if slo > 0 else math.inf)
    return ThrustCurve(source, prof["expo"], prof["interval"], prof["profile"], hover, h_iv,
                       keep, v_ref, v_from, decision, why_not, declared, prof["n_units"], prof["free_expo"],
                       lag_s=prof.get("lag_s", 0.0), lag_interval=prof.get("lag_interval", (0.0, 0.0)),
                       lag_decision=lag_decision, lag_tried_s=prof_lag["lag_s"],
                       smoothing_s=smooth["smoothing_s"], smoothings_s=smooth["admitted_s"],
                       smoothing_decision=smooth["decision"])
