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
of squares (exactly: the free fit b1·Σu + b2·Σu² is the same model with e = b2/(b1 + b2)), and
its 95 % interval is the
2.5-97.5 % percentiles of the minimum over a block bootstrap of (flight, time block) units
(:func:`droneid.dataset.validation.time_blocks`; each replicate re-profiles e). A flat profile gives a
wide interval: the output says so and never pretends a shape.

Battery compensation: the motors see the battery's voltage, so the thrust of a command falls as
it sags; ArduPilot scales its commands by V/V_ref to make up for it. The candidate reads every
command as u·V/V_ref (V_ref: the log's MOT_BAT_VOLT_MAX when declared, else the training
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

from droneid.fitting.decide import decide
from droneid.errors import ConfigError
from droneid.core.regression import blocked_cv, gram_bounded_lstsq, gram_bounded_lstsq_many, robust_fit, unit_grams
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
#: ArduPilot parameters that declare the thrust curve or the command normalisation
DECLARED = ("MOT_THST_EXPO", "MOT_THST_HOVER", "MOT_SPIN_MIN", "MOT_SPIN_MAX", "MOT_SPIN_ARM",
            "MOT_PWM_MIN", "MOT_PWM_MAX", "MOT_BAT_VOLT_MAX", "MOT_BAT_VOLT_MIN")
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
        shape = (f"thrust curve of {what}: (1 − e)·u + e·u²{norm}, e = {self.expo:.2f} [{lo:.2f}, {hi:.2f}] "
                 f"(95 %, block bootstrap over {self.n_units} (flight, block) units{over}; v̇z profiled with "
                 f"the thrust scale and drag refit at each e)")
        if self.at_bound:
            pull = (f"to {self.free_expo:.2f}" if math.isfinite(self.free_expo) else
                    "below 0" if self.expo == 0 else "above 1")
            shape += (f"; e sits on its bound {self.expo:g}: the data pull it {pull}, outside [0, 1] (the "
                      f"command map lacks something, e.g. a command normalisation the log does not declare)")
        elif not self.identified:
            shape += "; the flights hardly constrain the shape (a flat profile): e is a best guess"
        if self.lag_decision is not None:
            lo_l, hi_l = self.lag_interval
            shape += (f"; motor lag (first order on the thrust) {1000 * self.lag_tried_s:.0f} ms "
                      + (f"[{1000 * lo_l:.0f}, {1000 * hi_l:.0f}] ms kept (e profiled with it)" if self.lag_s else
                         "not kept") + f": {self.lag_decision.evidence}")
        hv = (f"; hover thrust fraction {self.hover:.3f} [{self.hover_interval[0]:.3f}, "
              f"{self.hover_interval[1]:.3f}]")
        dec = ""
        if "MOT_THST_EXPO" in self.declared or "MOT_THST_HOVER" in self.declared:
            parts = []
            if "MOT_THST_EXPO" in self.declared:
                parts.append(f"MOT_THST_EXPO {self.declared['MOT_THST_EXPO']:g} (identified {self.expo:.2f})")
            if "MOT_THST_HOVER" in self.declared:
                parts.append(f"MOT_THST_HOVER {self.declared['MOT_THST_HOVER']:.3g} (identified {self.hover:.3f})")
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
            return (f"The flights hardly constrain its thrust curve (e = {self.expo:.2f} [{lo:.2f}, {hi:.2f}]"
                    f"{beside}): trust it only for commands like the training flights'.")
        return (f"Thrust from the commands through the identified curve e = {self.expo:.2f} [{lo:.2f}, {hi:.2f}]"
                f"{beside}, {batt} battery compensation.")

    def to_dict(self) -> dict:
        return {"source": self.source, "expo": self.expo, "interval": list(self.interval),
                "identified": self.identified, "hover": self.hover, "hover_interval": list(self.hover_interval),
                "voltage": self.voltage, "v_ref": self.v_ref, "v_ref_from": self.v_ref_from,
                "voltage_decision": self.decision.to_dict() if self.decision is not None else None,
                "voltage_not_tried": self.why_not, "declared": dict(self.declared),
                "n_units": self.n_units, "offsets_s": list(self.offsets_s), "lag_s": self.lag_s,
                "lag_interval": list(self.lag_interval), "lag_tried_s": self.lag_tried_s,
                "lag_decision": self.lag_decision.to_dict() if self.lag_decision is not None else None, "free_expo": self.free_expo, "at_bound": self.at_bound,
                "profile": {f"{e:.2f}": v for e, v in self.profile.items()}}


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


def _best_expo(S: np.ndarray, grid: np.ndarray) -> float:
    """The e in [0, 1] that minimises the residual sum of squares of the gram ``S`` of [linear,
    quadratic, drag, y]: the free fit b1·linear + b2·quadratic + d·drag is the same model with
    e = b2 / (b1 + b2), exact where that lies in [0, 1] with positive thrust; otherwise the
    best of the profiled ``grid`` (an end of the range)."""
    return float(_best_expos(np.asarray(S, float)[None], grid)[0])


def _best_expos(S: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """:func:`_best_expo` of each gram of ``S`` (n, 4, 4), the free fits solved together."""
    b = gram_bounded_lstsq_many(S, np.array([-np.inf, -np.inf, 0.0]), np.full(3, np.inf))
    total = b[:, 0] + b[:, 1]
    e = np.full(S.shape[0], np.nan)
    inside = total > 0
    e[inside] = b[inside, 1] / total[inside]
    for i in np.flatnonzero(~(inside & (e >= 0.0) & (e <= 1.0))):
        rss, _ = _rss_profile(S[i], grid)
        e[i] = grid[int(np.argmin(rss))]
    return e


def _reduced(S: np.ndarray, e: float) -> np.ndarray:
    """The gram of [f_e column, drag, y] from the gram of [linear, quadratic, drag, y]."""
    return _reduced_many(np.asarray(S, float)[None], np.array([e], float))[0]


def _reduced_many(S: np.ndarray, e: np.ndarray) -> np.ndarray:
    """:func:`_reduced` of each gram of ``S`` (n, 4, 4) at its own ``e`` (n,)."""
    T = np.zeros((e.size, 3, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 2], T[:, 2, 3] = 1.0 - e, e, 1.0, 1.0
    return T @ S @ T.transpose(0, 2, 1)


_LO, _HI = np.zeros(2), np.full(2, np.inf)


def _rss_profile(S: np.ndarray, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(RSS at each e of ``grid``, (thrust scale, drag scale) at each) from the gram ``S``.

    Both scales are >= 0: a two-column non-negative least squares per e, solved in closed form
    for the whole grid at once (the optimum is the best feasible of the free solution, each column
    alone and none: the KKT points of a convex problem on the quadrant), which is what
    :func:`droneid.core.regression.gram_bounded_lstsq` finds one e at a time; an e where the two
    columns are collinear (or one is empty) goes through that general solver."""
    grid = np.asarray(grid, float)
    e, f = grid, 1.0 - grid
    # the reduced gram of [f_e column, drag, y]: f_e = (1 - e)·linear + e·quadratic
    a = f * f * S[0, 0] + 2.0 * f * e * S[0, 1] + e * e * S[1, 1]
    b = f * S[0, 2] + e * S[1, 2]
    p = f * S[0, 3] + e * S[1, 3]
    c, q, r = S[2, 2], S[2, 3], S[3, 3]
    det = a * c - b * b
    ok = (a > 0) & (c > 0) & (det > 1e-12 * a * c)
    with np.errstate(divide="ignore", invalid="ignore"):
        cands = [np.column_stack([(c * p - b * q) / det, (a * q - b * p) / det]),   # both free
                 np.column_stack([np.maximum(p / a, 0.0), np.zeros_like(a)]),     # drag at 0
                 np.column_stack([np.zeros_like(a), np.full_like(a, max(q / c, 0.0) if c > 0 else 0.0)]),
                 np.zeros((a.size, 2))]
    best_rss, beta = np.full(a.size, np.inf), np.zeros((a.size, 2))
    for B in cands:
        feasible = np.all(B >= 0.0, axis=1) & np.all(np.isfinite(B), axis=1)
        x, y_ = B[:, 0], B[:, 1]
        rss = r - 2.0 * (x * p + y_ * q) + x * x * a + 2.0 * x * y_ * b + y_ * y_ * c
        better = feasible & (rss < best_rss)
        best_rss[better], beta[better] = rss[better], B[better]
    for j in np.flatnonzero(~ok):
        R = _reduced(S, float(grid[j]))
        bj = gram_bounded_lstsq(R, _LO, _HI)
        best_rss[j] = R[2, 2] - 2.0 * bj @ R[:2, 2] + bj @ R[:2, :2] @ bj
        beta[j] = bj
    return best_rss, beta


#: first-order motor lags τ (s) profiled beside the shape (0: none)
LAG_GRID_S = tuple(round(0.005 * k, 3) for k in range(21))


def lagged(x: np.ndarray, t: np.ndarray, flight: np.ndarray, tau_s: float) -> np.ndarray:
    """``x`` (rows ordered by flight, then time ``t`` s) through a first-order lag of time constant
    ``tau_s``: dy/dt = (x − y)/τ, discretised exactly for x linear between rows (first-order
    hold: the rows are coarser than the lag). It restarts at y = x after a gap (a step over 1.5
    median steps) and at each flight's start. τ = 0: ``x`` itself."""
    x = np.asarray(x, float)
    if tau_s <= 0 or x.size < 2:
        return x.copy()
    t = np.asarray(t, float)
    dt = np.diff(t)
    step = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    restart = np.concatenate([[True], (np.asarray(flight)[1:] != np.asarray(flight)[:-1]) | (dt > 1.5 * step) | (dt <= 0)])
    h = np.concatenate([[step], np.where(dt > 0, dt, step)])
    a = np.exp(-h / tau_s)
    c = tau_s / h * (1.0 - a)
    y = np.empty_like(x)
    for i in range(x.size):
        y[i] = x[i] if restart[i] else a[i] * y[i - 1] + x[i] - a[i] * x[i - 1] - c[i] * (x[i] - x[i - 1])
    return y


def _min_rss(S: np.ndarray, grid: np.ndarray) -> tuple[float, float]:
    """(smallest residual sum of squares over e in [0, 1], its e) of the gram ``S``."""
    r, e = _min_rss_many(np.asarray(S, float)[None], grid)
    return float(r[0]), float(e[0])


def _min_rss_many(S: np.ndarray, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_min_rss` of each gram of ``S`` (n, 4, 4): (rss (n,), e (n,)), solved together."""
    e = _best_expos(S, grid)
    R = _reduced_many(S, e)
    b = gram_bounded_lstsq_many(R, _LO, _HI)
    bR = np.einsum("ni,nij->nj", b, R[:, :2, :2])
    return R[:, 2, 2] - 2.0 * np.einsum("ni,ni->n", b, R[:, :2, 2]) + np.einsum("nj,nj->n", bR, b), e


def profile_expo(linear: np.ndarray, quadratic: np.ndarray, drag: np.ndarray, y: np.ndarray,
                 units: np.ndarray, *, grid: Sequence[float] = EXPO_GRID, n_boot: int = N_BOOT_EXPO,
                 seed: int = 0, lag: tuple | None = None) -> dict:
    """The profile of the shape e of ``y ≈ a·((1 − e)·linear + e·quadratic) + d·drag`` (a, d >= 0
    refit at every e; ``y`` the target less its known physics, m/s²; the columns the thrust
    term at e = 0 and e = 1 and the drag term, on the same rows), with the robust (Huber) weights
    of the free fit of both columns. ``units``: (flight, block) ids of the rows. ``lag``: (t,
    flight) of the rows: the thrust terms also pass a first-order motor lag τ profiled over
    :data:`LAG_GRID_S` (:func:`lagged`; the lag is linear, so the shape stays linear in e).

    Returns {"expo", "free_expo" (the shape of the free fit, outside [0, 1] when the data pull e
    out of its range), "interval" (95 %), "scale" (a at e), "scale_interval", "profile" {e: RSS /
    min RSS}, "n_units", "lag_s", "lag_interval", "thrust" (the (linear, quadratic) columns at the
    chosen lag)}: e (and τ) from the least residual sum of squares (:func:`_best_expo`), the
    intervals from the minima of ``n_boot`` block-bootstrap replicates (each re-profiled)."""
    grid = np.asarray(grid, float)
    taus = LAG_GRID_S if lag is not None else (0.0,)
    cols = {tau: (lagged(linear, *lag, tau), lagged(quadratic, *lag, tau)) if tau else (linear, quadratic)
            for tau in taus}
    free_lo, free_hi = np.array([-np.inf, -np.inf, 0.0]), np.full(3, np.inf)
    # the robust weights of the free fit (the same model, e = b2 / (b1 + b2)) at the lag least
    # squares prefers: weights from a wrong shape or lag would depend on the noise where it
    # misfits and pull the estimate towards it
    plain = {tau: _min_rss(np.column_stack([*c, drag, y]).T @ np.column_stack([*c, drag, y]), grid)[0]
             for tau, c in cols.items()}
    tau0 = min(plain, key=plain.get)
    free = robust_fit(np.column_stack([*cols[tau0], drag]), y, free_lo, free_hi)
    grams = {}
    for tau, c in cols.items():
        ids, S_units, _ = unit_grams(np.column_stack([*c, drag]), y, free.weights, np.asarray(units))
        grams[tau] = S_units
    fits = {tau: _min_rss(Su.sum(axis=0), grid) for tau, Su in grams.items()}
    tau_hat = min(fits, key=lambda k: fits[k][0])
    S = grams[tau_hat].sum(axis=0)
    e = fits[tau_hat][1]
    rss, _ = _rss_profile(S, grid)
    a = float(gram_bounded_lstsq(_reduced(S, e), _LO, _HI)[0])
    # every replicate at every lag solved together: replicate i's unit counts (drawn replicate by
    # replicate, as one at a time would), its lag the first of the least RSS
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, ids.size, (n_boot, ids.size))
    counts = np.stack([np.bincount(d, minlength=ids.size) for d in draws]).astype(float)
    Sb = np.stack([(counts @ grams[tau].reshape(ids.size, -1)).reshape(n_boot, *S.shape) for tau in taus])
    r, eb = _min_rss_many(Sb.reshape(-1, *S.shape), grid)
    k = np.argmin(np.where(np.isnan(r), np.inf, r).reshape(len(taus), n_boot), axis=0)
    pick = np.arange(n_boot)
    es = eb.reshape(len(taus), n_boot)[k, pick]
    lags = np.asarray(taus, float)[k]
    scales = gram_bounded_lstsq_many(_reduced_many(Sb[k, pick], es), _LO, _HI)[:, 0]
    lo, hi = np.percentile(es, [2.5, 97.5])
    slo, shi = np.percentile(scales, [2.5, 97.5])
    best_rss = float(np.min(rss)) if np.min(rss) > 0 else 1.0
    b = gram_bounded_lstsq(S, free_lo, free_hi)
    free_e = float(b[1] / (b[0] + b[1])) if b[0] + b[1] > 0 else math.nan
    return {"expo": e, "free_expo": free_e, "interval": (float(lo), float(hi)), "scale": a,
            "scale_interval": (float(slo), float(shi)),
            "profile": {float(g): float(r / best_rss) for g, r in zip(grid, rss)}, "n_units": int(ids.size),
            "lag_s": float(tau_hat), "lag_interval": tuple(float(v) for v in np.percentile(lags, [2.5, 97.5])),
            "thrust": cols[tau_hat]}


def _columns(prior, ds):
    """(linear thrust column, quadratic one, drag column, y less the known physics) of v̇z on
    the dataset ``ds`` for the command prior ``prior`` (its v_ref as given)."""
    cols = ds.columns()
    out = []
    for e in (0.0, 1.0):
        p = prior.with_params(expo=e)
        m = prior_terms(p, _TARGET)
        A, yy, _, _ = m._problem(cols, ds.y)
        feats = split_terms(p, _TARGET)
        thrust = [i for i, f in enumerate(feats) if f.role == "thrust"]
        drag = [i for i, f in enumerate(feats) if f.role == "drag"]
        out.append(A[:, thrust].sum(axis=1))
    return out[0], out[1], A[:, drag].sum(axis=1), yy


def over_offsets(curve: ThrustCurve, train_flights, prior, cfg, cuts, signals: Sequence[str],
                 offsets: Sequence[float], *, seed: int = 0) -> ThrustCurve:
    """``curve`` (chosen with the commands read at one offset) with its interval widened to the
    hull of the intervals at every offset of ``offsets`` (the offsets the chosen one does not
    beat, :class:`droneid.planning.plan.OffsetDecision`): how the commands lead their thrust is itself
    uncertain (a motor lag is no pure offset), and the shape moves with it. ``prior``: the
    command prior with the curve's battery compensation."""
    from droneid.planning.plan import dataset_builder, train_rows

    lo, hi = curve.interval
    inputs = tuple(prior.inputs(_TARGET))
    for d in offsets:
        ds = train_rows(dataset_builder(cfg, {s: float(d) for s in signals}).build(
            list(train_flights), target=_TARGET, inputs=inputs), cuts)
        if len(ds) < 30:
            continue
        prof = profile_expo(*_columns(prior, ds), time_blocks(ds.t, ds.flight, alpha=VOLTAGE_ALPHA), seed=seed)
        lo, hi = min(lo, prof["interval"][0]), max(hi, prof["interval"][1])
    return replace(curve, interval=(lo, hi), offsets_s=(min(offsets), max(offsets)) if len(offsets) else ())


def choose_thrust_curve(train_flights, prior, cfg, cuts=None, delays=None, *, seed: int = 0) -> ThrustCurve | None:
    """The thrust curve of a command prior (``prior.params["source"]`` in
    :data:`priors.thrust.COMMAND_SOURCES`) from the training rows of v̇z (``cuts``: hold-out
    starts, ``delays``: {signal: s} the thrust inputs are read at), with the battery
    compensation decided by the block test; None for another prior or without v̇z rows."""
    from droneid.planning.plan import dataset_builder, train_rows    # plan composes this stage

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
    ds = train_rows(dataset_builder(cfg, delays).build(list(train_flights), target=_TARGET, inputs=inputs), cuts)
    if len(ds) < 30:
        return None
    blocks = time_blocks(ds.t, ds.flight, alpha=VOLTAGE_ALPHA)
    if have_v:
        volts = np.asarray(ds.columns()["battery_voltage"], float)
        if declared.get("MOT_BAT_VOLT_MAX", 0) > 0:
            v_ref, v_from = float(declared["MOT_BAT_VOLT_MAX"]), "the log's MOT_BAT_VOLT_MAX"
        elif volts.size and float(np.max(volts)) > 0:
            v_ref, v_from = float(np.round(np.max(volts), 2)), "the training flights' highest voltage"
        else:
            why_not = "no positive battery voltage on the training rows"
    else:
        why_not = "the training flights do not all log a battery voltage"
    prof = profile_expo(*_columns(base, ds), blocks, seed=seed)
    decision, keep = None, False
    if v_ref is not None:
        cand = prior.with_params(v_ref=v_ref)
        prof_v = profile_expo(*_columns(cand, ds), blocks, seed=seed)
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
    L, Q, D, yy = _columns(prior.with_params(v_ref=v_ref if keep else None), ds)
    prof_lag = profile_expo(L, Q, D, yy, blocks, seed=seed, lag=(ds.t, ds.flight))
    lag_decision = None
    if prof_lag["lag_s"] > 0:
        def held_out(p):
            e = p["expo"]
            lin, quad = p["thrust"]
            return yy - blocked_cv(np.column_stack([(1 - e) * lin + e * quad, D]), yy, blocks, _LO, _HI)
        try:
            lag_decision = decide(held_out(prof), held_out(prof_lag), blocks, alpha=LAG_ALPHA,
                                  what=f"motor lag {1000 * prof_lag['lag_s']:.0f} ms")
        except ConfigError:
            lag_decision = None
        if lag_decision is not None and lag_decision.accepted:
            prof = prof_lag
    motors = int(prior.params.get("motors", 1)) if source == "motor" else 1
    g = float(prior.params.get("g", 9.81))
    k_nom = float(prior.params.get("k_T", 1.0))
    # the thrust at full command on every motor, m/s²: the fitted scale times the nominal k_T per
    # unit of f_e, times N
    full = lambda s: s * k_nom * motors   # noqa: E731
    hover = g / full(prof["scale"]) if prof["scale"] > 0 else math.nan
    slo, shi = prof["scale_interval"]
    h_iv = (g / full(shi) if shi > 0 else math.nan, g / full(slo) if slo > 0 else math.inf)
    return ThrustCurve(source, prof["expo"], prof["interval"], prof["profile"], hover, h_iv,
                       keep, v_ref, v_from, decision, why_not, declared, prof["n_units"], prof["free_expo"],
                       lag_s=prof.get("lag_s", 0.0), lag_interval=prof.get("lag_interval", (0.0, 0.0)),
                       lag_decision=lag_decision, lag_tried_s=prof_lag["lag_s"])
