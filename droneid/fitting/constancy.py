"""Vehicle constants across flights: does a coefficient hold from flight to flight, and how well
is it known once the flights' disagreement is counted?

A model's coefficients are of two kinds (docs/estimates.md):

- **vehicle constants**: the scales of the prior's thrust, thrust-direction (tilt) and drag
  terms (:data:`VEHICLE_CONSTANT_ROLES`); they belong to the airframe and must hold on every
  flight of it;
- **flight conditions**: a clock offset between two log streams, wind, battery state, payload;
  estimated per flight (wind already is: the diagnosis gives each flight its own).

A pooled fit of many flights gives one value for a vehicle constant whatever the flights say,
and a block bootstrap of it measures only the noise inside the flights: when the model lacks
something, the constant absorbs it differently on every flight and the pooled interval is
narrow around a value that holds nowhere. This module tests that and widens the interval:

1. **Per-unit estimates.** The same terms are fitted on each flight alone (with one flight: on
   each of :func:`n_stretches` contiguous stretches of it), each with its block-bootstrap
   standard error (the spread of :func:`droneid.core.regression.bootstrap_draws` over the unit's
   own time blocks).
2. **Constancy test** (:func:`heterogeneity`): Cochran's Q, ``Q = Σ w_i (θ_i − θ̄)²`` with
   ``w_i = 1/se_i²`` and θ̄ their weighted mean, read as Welch's (1951) test for means with
   unequal variances: each ``se_i`` is itself estimated, from the unit's B_i time blocks, so it
   carries ``ν_i = B_i − 1`` degrees of freedom (as batch means do), and under "one value, the
   flights differ by their noise only" ``F = Q / (k − 1) / (1 + 2(k − 2) Λ / (k² − 1))`` with
   ``Λ = Σ (1 − w_i/W)² / ν_i`` is F(k − 1, (k² − 1) / (3 Λ)) (χ²(k − 1) / (k − 1) when the
   standard errors are known). Read as χ²(k − 1), five units with ten-block standard errors
   exact in expectation were called NOT constant 4 % of the time at a 1 % level (Welch: 1.1 %),
   and 3 of 40 planted torque-gain sets (Welch: 1); B − 1 is a ceiling on a regression
   coefficient's bootstrap degrees of freedom (the planted torque gains' behave like 4-8 of 9),
   so the test stays somewhat liberal (docs/estimates.md). A
   coefficient whose ``p`` falls below :data:`ALPHA` (Holm over the target's vehicle constants)
   and whose between-unit spread τ (below) is at least :data:`MIN_TAU_REL` of its value is
   **not constant**: not a property of this vehicle under this model. The bootstrap's standard
   errors are inflated by ``B/(B − 1)`` (B blocks) to undo the block bootstrap's known
   small-sample shrinkage; the test's size is measured on simulated flights with the model right
   (benchmarks/bench_intervals.py).
3. **Between-flight interval** (:func:`heterogeneity`): the random-effects mean of the
   per-flight values (DerSimonian-Laird τ²) with the Hartung-Knapp-Sidik-Jonkman interval,
   ``μ ± t(k−1) · √(max(q, 1) / Σ w*)``, ``w* = 1/(se² + τ²)``: an interval for the constant
   that counts how much flights disagree (with few flights it is wide, as it must be). The
   coefficient's reported interval is the hull of this and the pooled block bootstrap. With one
   flight no such interval exists: the output says the interval cannot include flight-to-flight
   variation.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import special    # chdtrc, stdtrit: scipy.stats' chi2.sf and t.ppf, without its 0.5 s import

from droneid.core.regression import RobustFit, bootstrap_draws, robust_fit

__all__ = ["Constancy", "spread_text", "ALPHA", "VEHICLE_CONSTANT_ROLES", "MIN_UNIT_ROWS", "MIN_TAU_REL", "n_stretches", "units_of",
           "heterogeneity", "holm_flags", "constancy_line", "constancy_sentence", "leads", "LEADS",
           "SHARED_ROLES", "SharedConstant", "across_targets", "moved", "se_of_interval", "rule_text",
           "unit_estimate", "unit_bounds", "informative", "constancies", "new_flight_expectation", "new_flight_p"]

#: the prior-term roles whose coefficients are constants of the vehicle (priors.base.ROLES)
VEHICLE_CONSTANT_ROLES = ("thrust", "tilt", "drag")
#: family-wise level of "not constant" over one target's vehicle constants (Holm)
ALPHA = 0.01
#: a flight or stretch with fewer training rows is not fitted alone
MIN_UNIT_ROWS = 40
#: the smallest between-unit spread (τ, relative to the mean) called "not constant": as the
#: decision rule's minimum effect (:mod:`droneid.fitting.decide`), a consistent but negligible spread
#: (long flights make any difference significant) is not a finding
MIN_TAU_REL = 0.01


def n_stretches(n_rows: int) -> int:
    """Contiguous stretches one flight is cut into for its constancy test: 4, fewer when a
    stretch would have under :data:`MIN_UNIT_ROWS` rows (0: too short to test)."""
    k = min(4, n_rows // MIN_UNIT_ROWS)
    return k if k >= 2 else 0


def units_of(t: np.ndarray, flight: np.ndarray, sources: Sequence[str]) -> tuple[np.ndarray, list[str], str]:
    """(unit id per row, unit names, kind): the training flights when there are 2 or more
    (``kind`` "flight"), else the stretches of the one flight (``kind`` "stretch", named by their
    time span); ids are -1 for rows of no unit."""
    t = np.asarray(t, float)
    flight = np.asarray(flight, int)
    ids = np.unique(flight)
    if ids.size >= 2:
        names = [str(sources[f]) if f < len(sources) else f"flight {f}" for f in ids]
        return np.searchsorted(ids, flight), names, "flight"
    k = n_stretches(t.size)
    unit = np.full(t.size, -1)
    if not k:
        return unit, [], "stretch"
    order = np.argsort(t, kind="stable")
    unit[order] = np.minimum(k * np.arange(t.size) // t.size, k - 1)
    names = [f"{t[unit == u].min():.1f}-{t[unit == u].max():.1f} s" for u in range(k)]
    return unit, names, "stretch"


def heterogeneity(values, se, df=None) -> dict:
    """The constancy test (Cochran's Q read as Welch's test) and the random-effects (HKSJ)
    interval of per-unit estimates ``values`` with standard errors ``se`` on ``df`` degrees of
    freedom each (None: known standard errors, Q ~ χ²(k − 1)); see the module docstring. Returns
    ``{"p", "q", "tau", "mean", "low", "high"}``; ``p`` is NaN with fewer than 2 units. A unit
    whose standard error is not positive carries no information (its rows do not move the term:
    its estimate is whatever the solver returns, with no spread; :func:`unit_bounds` keeps a unit's
    estimate off the bounds, where the spread also collapsed) and does not count."""
    v = np.asarray(values, float)
    s = np.asarray(se, float)
    keep = informative(v, s)
    if df is not None and np.ndim(df):
        df = np.asarray(df, float)[keep]
    v, s = v[keep], s[keep]
    k = v.size
    if k < 2:
        return {"p": math.nan, "q": math.nan, "tau": math.nan, "mean": float(v[0]) if k else math.nan,
                "low": math.nan, "high": math.nan}
    var = s ** 2
    w = 1.0 / var
    fixed = float(np.sum(w * v) / np.sum(w))
    q = float(np.sum(w * (v - fixed) ** 2))
    p = _welch_p(q, w, df)
    c = float(np.sum(w) - np.sum(w * w) / np.sum(w))
    tau2 = max(0.0, (q - (k - 1)) / c) if c > 0 else 0.0
    ws = 1.0 / (var + tau2)
    mu = float(np.sum(ws * v) / np.sum(ws))
    qs = float(np.sum(ws * (v - mu) ** 2)) / (k - 1)
    half = float(special.stdtrit(k - 1, 0.975)) * math.sqrt(max(qs, 1.0) / float(np.sum(ws)))
    return {"p": p, "q": q, "tau": math.sqrt(tau2), "mean": mu, "low": mu - half, "high": mu + half}


def _welch_p(q: float, w: np.ndarray, df) -> float:
    """p of Cochran's ``q`` over units of weights ``w`` (1/se²) whose standard errors have ``df``
    degrees of freedom (None or all infinite: χ²(k − 1)), by Welch's approximation (module
    docstring)."""
    k = w.size
    nu = np.full(k, math.inf) if df is None else np.broadcast_to(np.asarray(df, float), (k,))
    lam = float(np.sum((1.0 - w / np.sum(w)) ** 2 / np.maximum(nu, 1.0)))
    if lam <= 0.0:
        return float(special.chdtrc(k - 1, q))
    f = q / (k - 1) / (1.0 + 2.0 * (k - 2) / (k * k - 1) * lam)
    return float(special.fdtrc(k - 1, (k * k - 1) / (3.0 * lam), f))


def informative(values, se) -> np.ndarray:
    """Which units' estimates ``values`` with standard errors ``se`` carry information for the
    constancy test: finite, and a standard error above 1e-9 of max(|value|, 1) (below it the unit's
    rows do not move the term, and its weight would decide Q alone)."""
    v, s = np.asarray(values, float), np.asarray(se, float)
    return np.isfinite(v) & np.isfinite(s) & (s > 1e-9 * np.maximum(np.abs(np.nan_to_num(v)), 1.0))


def unit_bounds(lo, hi, tested=None) -> tuple[np.ndarray, np.ndarray]:
    """The bounds of a unit's own fit for the constancy test: the coefficients ``tested`` (indices;
    None: all) lose their physics bounds (a drag or a gain never negative) unless held (``lo ==
    hi``); the others (the model's other terms, trims) keep theirs. The test asks
    whether the units' estimates agree, and an estimate pinned at a bound is not an estimate: its
    bootstrap replicates pile up on the bound, its standard error falls towards 0, and its weight
    1/se² then decides Cochran's Q alone, whichever way. Unbounded, a flight that pushes a
    coefficient through its bound says how far, with the spread its data give it. The model's
    coefficients keep their bounds; the reported interval is clipped to them."""
    lo = np.array(lo, float)
    hi = np.array(hi, float)
    free = np.zeros(lo.size, bool)
    free[slice(None) if tested is None else list(tested)] = True
    free &= lo != hi
    lo[free], hi[free] = -np.inf, np.inf
    return lo, hi


def unit_estimate(A: np.ndarray, y: np.ndarray, blocks: np.ndarray, lo=None, hi=None, *,
                  seed: int = 0) -> tuple["RobustFit", np.ndarray, np.ndarray, float]:
    """One unit's own fit (a flight or a stretch): ``(fit, se, pct, df)``, its robust fit
    (:class:`droneid.core.regression.RobustFit`), the standard
    error of each coefficient over the block bootstrap of its own time ``blocks``
    (:func:`~droneid.core.regression.bootstrap_draws`, Huber's factor included, inflated by
    ``B/(B − 1)`` for B blocks: the block bootstrap's small-sample shrinkage), the (2, k) percentile 95 % interval of those draws
    and the standard errors' degrees of freedom, B − 1."""
    f = robust_fit(A, y, lo, hi)
    b = np.unique(blocks).size
    draws = bootstrap_draws(A, y, blocks, f, lo, hi, seed=seed)
    se = np.std(draws, axis=0, ddof=1) * math.sqrt(b / max(b - 1, 1))
    return f, se, np.percentile(draws, [2.5, 97.5], axis=0), float(max(b - 1, 1))


def constancies(kind: str, names: Sequence[str], vals, ses, ivs, labels: Mapping[int, str],
                physical: Mapping[int, tuple[float, str] | None] | None = None, dfs=None) -> dict[str, "Constancy"]:
    """{label: :class:`Constancy`} of the coefficients ``labels`` (column index: name) from the
    per-unit estimates of :func:`unit_estimate` (``vals``, ``ses`` (U, k), ``ivs`` U × (2, k),
    ``dfs`` (U,) the standard errors' degrees of freedom, None: known) of
    the units ``names`` of ``kind``: each tested and combined by :func:`heterogeneity`, flagged by
    Holm over ``labels`` (:func:`holm_flags`) and the spread rule (:func:`moved`); {} with fewer
    than two units."""
    if len(names) < 2:
        return {}
    vals, ses = np.asarray(vals, float), np.asarray(ses, float)
    het = {lab: heterogeneity(vals[:, i], ses[:, i], dfs) for i, lab in labels.items()}
    used = {i: informative(vals[:, i], ses[:, i]) for i in labels}      # the units each test counted
    flags = holm_flags({lab: h["p"] for lab, h in het.items()})
    out = {}
    df = np.broadcast_to(np.asarray(np.inf if dfs is None else dfs, float), (len(names),))
    for i, lab in labels.items():
        h = het[lab]
        out[lab] = Constancy(
            kind, {name: (float(vals[j, i]), float(ivs[j][0, i]), float(ivs[j][1, i])) for j, name in enumerate(names)
                   if used[i][j]},
            h["p"], (not moved(flags[lab], h["tau"], h["mean"])) if math.isfinite(h["p"]) else None,
            (h["low"], h["high"]) if kind == "flight" else None, h["tau"], (physical or {}).get(i),
            {name: (float(ses[j, i]), float(df[j])) for j, name in enumerate(names) if used[i][j]})
    return out


def new_flight_expectation(value: float, low: float, high: float, constancy: Mapping | None) -> dict:
    """What a NEW flight of the vehicle should give for a constant identified as ``value`` [``low``,
    ``high``] (95 %) with its constancy record ``constancy`` (:meth:`Constancy.to_dict`, or None):
    ``{"value", "se", "df", "flights"}``. With two or more training flights, the random-effects mean μ
    of their values (the middle of the between-flight interval) and the spread of a new flight
    about it, √(se_μ² + τ²) (se_μ from the Hartung-Knapp interval), with k − 1 degrees of freedom;
    otherwise ``value`` and the standard error its interval stands for (normal)."""
    out = {"value": float(value), "se": se_of_interval(low, high), "df": math.inf, "flights": 1}
    c = constancy or {}
    per = c.get("per_flight") or {}
    between, tau = c.get("between"), c.get("tau")
    if c.get("unit") == "flight" and len(per) >= 2 and between and tau is not None and math.isfinite(float(tau)):
        k = len(per)
        b_lo, b_hi = float(between[0]), float(between[1])
        se_mu = (b_hi - b_lo) / 2 / float(special.stdtrit(k - 1, 0.975))
        out.update(value=(b_lo + b_hi) / 2, se=math.hypot(se_mu, float(tau)), df=float(k - 1), flights=k)
    return out


def new_flight_p(value: float, se: float, expected: Mapping, df: float = math.inf) -> float:
    """Two-sided p of a flight's own estimate ``value`` ± ``se`` (on ``df`` degrees of freedom, as
    :func:`unit_estimate` gives them) against :func:`new_flight_expectation`'s ``expected``:
    ``t = (θ − μ) / √(se² + se_new²)`` on the Welch-Satterthwaite degrees of freedom of the two,
    at most the expectation's own (k − 1 flights: its spread τ, from k flights, is noisier than
    that count says, so the combination may not claim more) (NaN: no test)."""
    se, se_new = float(se), float(expected["se"])
    if not se > 0 and not se_new > 0:
        return math.nan
    t = (float(value) - expected["value"]) / math.hypot(se, se_new)
    if not math.isfinite(t):
        return math.nan
    parts = [x ** 4 / max(d, 1.0) for x, d in ((se, float(df)), (se_new, float(expected["df"])))
             if math.isfinite(d) and x > 0]
    dof = (se * se + se_new * se_new) ** 2 / sum(parts) if parts else math.inf
    dof = min(dof, float(expected["df"]))       # the spread τ is the noisier part: never past its k − 1
    return float(special.erfc(abs(t) / math.sqrt(2))) if math.isinf(dof) else float(2 * special.stdtr(dof, -abs(t)))


def moved(flagged: bool, spread: float, value: float) -> bool:
    """The constancy rule's verdict "NOT constant" (one home for every test of a vehicle constant:
    across flights, across targets, on a predicted flight): the test ``flagged`` it (Holm at
    :data:`ALPHA`) and the ``spread`` (τ, or a difference) is at least :data:`MIN_TAU_REL` of
    ``value``: a significant but negligible difference is no finding."""
    return bool(flagged) and math.isfinite(spread) and spread >= MIN_TAU_REL * abs(value)


def se_of_interval(low: float, high: float) -> float:
    """The standard error a reported 95 % interval stands for: its half-width / 1.96 (a
    normal-theory reading of a percentile or hull interval: approximate where it is skewed)."""
    return (high - low) / (2 * 1.959964)


def rule_text(what: str) -> str:
    """The constancy rule in words, after ``what`` was estimated (for a report line)."""
    return f"{what}; Holm at α = {ALPHA:g}, and a difference of {100 * MIN_TAU_REL:g} % or more"


def holm_flags(p_values: Mapping[str, float], alpha: float = ALPHA) -> dict[str, bool]:
    """{name: not constant} by Holm's step-down at ``alpha`` over the p-values given (NaN: never
    flagged, and not counted in the family)."""
    named = sorted(((p, n) for n, p in p_values.items() if math.isfinite(p)))
    flags = {n: False for n in p_values}
    m = len(named)
    for k, (p, n) in enumerate(named):
        if p < alpha / (m - k):
            flags[n] = True
        else:
            break
    return flags


@dataclass(frozen=True)
class Constancy:
    """The constancy of one vehicle constant (result.json ``targets.<t>.constancy.<coefficient>``).

    unit : "flight" (one estimate per training flight) or "stretch" (one training flight, cut in
        contiguous stretches of time); per_unit : {unit name: (value, low, high)}, each unit's own
        fit with its 95 % block-bootstrap interval; p : the constancy test's p-value (Cochran's Q read as Welch's test; NaN: untestable);
    constant : False when the test flags it (Holm at :data:`ALPHA` over the target's vehicle
        constants, τ ≥ :data:`MIN_TAU_REL` of the value), True otherwise, None when untestable; between : (low, high) the
        random-effects (HKSJ) 95 % interval of the constant over the flights (None for
        stretches: one flight cannot show flight-to-flight variation); tau : the between-unit
        standard deviation (DerSimonian-Laird), in the coefficient's units; physical : (factor,
        unit) turning the coefficient (a scale on nominal) into a physical value, e.g. (0.28,
        "1/s") for a linear drag, or None; noise : {unit name: (se, df)}, each unit's standard
        error as the test read it and its degrees of freedom (inf: known), in memory only (not in
        result.json: a record read back has {})
    """
    unit: str
    per_unit: Mapping[str, tuple[float, float, float]]
    p: float
    constant: bool | None
    between: tuple[float, float] | None = None
    tau: float = math.nan
    physical: tuple[float, str] | None = field(default=None)
    noise: Mapping[str, tuple[float, float]] = field(default_factory=dict, compare=False, repr=False)

    def spread(self) -> tuple[float, float]:
        """(lowest, highest) per-unit value."""
        vals = [v[0] for v in self.per_unit.values()]
        return (min(vals), max(vals)) if vals else (math.nan, math.nan)

    def to_dict(self) -> dict:
        return {"unit": self.unit, "per_flight" if self.unit == "flight" else "per_stretch":
                {k: list(v) for k, v in self.per_unit.items()},
                "p": self.p, "constant": self.constant,
                "between": list(self.between) if self.between is not None else None,
                "tau": self.tau, "physical": list(self.physical) if self.physical is not None else None}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Constancy":
        per = d["per_flight"] if "per_flight" in d else d["per_stretch"]
        return cls(str(d["unit"]), {k: tuple(float(x) for x in v) for k, v in per.items()},
                   float(d["p"]) if d["p"] is not None else math.nan, d["constant"],
                   tuple(d["between"]) if d["between"] is not None else None,
                   float(d["tau"]) if d["tau"] is not None else math.nan,
                   (float(d["physical"][0]), str(d["physical"][1])) if d["physical"] is not None else None)


def _span(c: Constancy) -> str:
    lo, hi = c.spread()
    text = f"{lo:.3g}-{hi:.3g}"
    if c.physical is not None:
        k, unit = c.physical
        text += f" (= {k * lo:.3g}-{k * hi:.3g} {unit})"
    return text


def spread_text(rel_pct: float) -> str:
    """A spread τ relative to its mean, for people: "1.3 %", "150 %" (not "1.5e+02 %"); "—" where
    it has no relative size (a mean of 0)."""
    if not math.isfinite(rel_pct):
        return "—"
    return f"{rel_pct:.2g} %" if rel_pct < 10 else f"{rel_pct:.0f} %"


def constancy_line(constancy: Mapping[str, Constancy]) -> str:
    """One line for a report: each vehicle constant's range over the units, its p and verdict;
    empty without any."""
    if not constancy:
        return ""
    first = next(iter(constancy.values()))
    n = len(first.per_unit)
    where = (f"the {n} training flights" if first.unit == "flight" else
             f"{n} stretches of the one training flight (one flight cannot show how flights differ: "
             f"its intervals leave that out)")
    parts = []
    for lab, c in constancy.items():
        vals = [v[0] for v in c.per_unit.values()]
        rel = 100 * c.tau / abs(float(np.mean(vals))) if vals and np.mean(vals) != 0 else math.nan
        verdict = {True: "constant", False: "NOT constant", None: "untestable"}[c.constant]
        if c.constant and rel >= 100 * MIN_TAU_REL:     # a wide spread the test does not flag
            verdict = "constant within its noise"
        parts.append(f"{lab} {_span(c)}, p = {c.p:.2g}, spread τ {spread_text(rel)}: {verdict}")
    return (f"  constancy over {where} (each fitted alone; Cochran's Q as Welch's test, Holm at α = {ALPHA:g}, "
            f"and a spread τ of {100 * MIN_TAU_REL:g} % or more): "
            + "; ".join(parts))


#: catalogue effects (priors/effect_catalogue) that make a coefficient of this role move between
#: flights when the model lacks them: where to look when it is NOT constant
LEADS = {"drag": ("wind", "quadratic_drag", "anisotropic_drag", "vertical_drag"),
         "thrust": ("battery_sag", "thrust_curve", "motor_thrust", "ground_effect"),
         "tilt": ("attitude_bias", "attitude_delay", "thrust_direction")}


#: flight conditions droneid does not estimate per flight that move a coefficient of this role
CONDITION_LEADS = {"thrust": "a payload or a battery that differs between flights (the thrust per unit mass moves)",
                   "drag": "a wind that differs between flights, or headings that differ with a drag along the body axes"}


def leads(constancy: Mapping[str, Constancy], diagnosis: Mapping, offset=None, curve=None) -> str:
    """Where to look when vehicle constants are NOT constant, one sentence ("" when all hold):
    the flight conditions droneid saw differ between the flights (the clock offset, ``offset``:
    the plan's :class:`~droneid.planning.plan.OffsetDecision`) and the catalogue effects that move such a
    coefficient, with what the diagnosis (``diagnosis``: the plan's summary) said of each; a
    command-driven vehicle's thrust curve (``curve``: the plan's
    :class:`~droneid.fitting.thrust_curve.ThrustCurve`) holds the thrust curve and, where kept, the
    battery compensation (the diagnosis does not try them then: they are not 'not tried')."""
    bad = [lab for lab, c in constancy.items() if c.constant is False]
    if not bad:
        return ""
    roles = sorted({"drag" if "kD" in lab or "drag" in lab else "thrust" if "sum_" in lab or "thrust" in lab
                    else "tilt" for lab in bad})
    said = {**{e: "not detected" for e in diagnosis.get("not_detected", ())},
            **{e: "untestable" for e in diagnosis.get("untestable", {})},
            **{e: "added" for e in diagnosis.get("effects_added", ())}}
    if curve is not None:
        said["thrust_curve"] = f"in the model: the curve's shape e = {curve.expo:.2f}"
        said["battery_sag"] = ("in the model: the curve's battery compensation" if curve.voltage else
                               "the curve's battery compensation not kept")
    out = []
    if offset is not None and getattr(offset, "per_flight", None) and not offset.flights_share:
        out.append("the flights' thrust clock offsets differ (" + ", ".join(
            f"{n} {1000 * d:+.0f} ms" for n, d in offset.applied.items()) + " read at their own offsets, the "
            f"others at {1000 * offset.offset_s:+.0f} ms)")
    for role in roles:
        cands = [f"{e} ({said.get(e, 'not tried')})" for e in LEADS[role]]
        out.append(f"effects that move a {role} scale between flights: " + ", ".join(cands)
                   + (f"; or a condition of each flight: {CONDITION_LEADS[role]}" if role in CONDITION_LEADS else ""))
    return "leads for the constants that move: " + "; ".join(out)


def constancy_sentence(constancy: Mapping[str, Constancy]) -> str:
    """The verdict's words on the vehicle constants that do not hold across the units ("" when
    every one holds or none was tested)."""
    bad = [(lab, c) for lab, c in constancy.items() if c.constant is False]
    if not bad:
        return ""
    among = "flights" if bad[0][1].unit == "flight" else "stretches of the flight"
    names = "; ".join(f"{lab} {_span(c)}" for lab, c in bad)
    return (f"NOT vehicle constants: {names} differ between the training {among} by more than their "
            f"noise allows: not a property of this vehicle under this model (something the model lacks "
            f"moves them)")


# ------------------------------------------------------------------------------------------------
# one constant across the targets

#: prior-term roles whose scale is one constant of the vehicle whatever the target: the thrust
#: (and, at hover balance, the thrust direction's) scale is the same along world x, y and z (one
#: vehicle has one thrust per unit mass); drag scales may differ by axis and are not compared
SHARED_ROLES = ("thrust", "tilt")


#: what each shared role's scale is, in the words of a verdict
_SHARED_WORDS = {"thrust": ("THRUST", "thrust scale", "thrust per unit mass"),
                 "tilt": ("THRUST-DIRECTION", "thrust-direction (tilt) scale", "thrust per unit mass at hover")}


@dataclass(frozen=True)
class SharedConstant:
    """One vehicle constant as several targets' terms estimate it (the thrust scale along world x,
    y and z): Cochran's Q, as in :class:`Constancy`, but read as χ²(k − 1) with each term's
    95 % interval as its estimate's known noise (:func:`se_of_interval`: no degrees of freedom to
    count).

    role : the terms' role (:data:`SHARED_ROLES`); per_term : {term label: (value, low, high)};
    p : Cochran's Q p-value; tau : the between-term spread (DerSimonian-Laird), in the
    coefficient's units; mean : the random-effects mean the spread is measured against;
    constant : False when the rule says so (:func:`moved`: p below :data:`ALPHA`, Holm over the
    roles tested, and τ at least :data:`MIN_TAU_REL` of the mean), True otherwise.
    The targets' estimates are treated as independent (each target's residuals are its own
    axis's). What they share (the input offset's uncertainty that widens every interval, a
    payload that moves every axis's scale together) makes the true variance of a difference
    smaller than the sum, so the test is conservative: it flags less often than its level. A
    term held at its nominal value or pulled to a bound is not an estimate and is left out."""
    role: str
    per_term: Mapping[str, tuple[float, float, float]]
    p: float
    tau: float
    constant: bool
    mean: float = math.nan

    def _spread_pct(self) -> str:
        return spread_text(100 * self.tau / abs(self.mean) if self.mean else math.nan)

    def sentence(self, labels: Sequence[str]) -> str:
        """The verdict's words for a target whose terms ``labels`` are among these ("" when the
        constant holds, or none of ``labels`` is here)."""
        if self.constant or not any(lab in self.per_term for lab in labels):
            return ""
        mine = [lab for lab in self.per_term if lab in labels]
        others = [lab for lab in self.per_term if lab not in labels]
        said = "; ".join(f"{lab} {v:.4g} [{lo:.4g}, {hi:.4g}]" for lab in mine + others
                         for v, lo, hi in (self.per_term[lab],))
        caps, scale, per_mass = _SHARED_WORDS.get(self.role, (self.role.upper(), f"{self.role} scale", self.role))
        return (f"NOT ONE {caps} SCALE: {said} differ between the targets by more than their noise allows "
                f"(Cochran's Q p = {self.p:.2g}, spread τ {self._spread_pct()}): one vehicle has one "
                f"{per_mass}, so at least one of these fits absorbs something its model lacks (a weakly "
                f"excited axis, whose attitude noise pulls its scale toward 0; an attitude bias; an effect of "
                f"one axis) and its {scale} is not the vehicle's.")

    def note(self) -> str:
        """One line for the run's notes: what was tested and its outcome."""
        _, scale, _ = _SHARED_WORDS.get(self.role, ("", f"{self.role} scale", ""))
        if not self.constant:
            said = "they DIFFER (the verdicts say so)"
        elif self.p < ALPHA:
            said = f"they agree within {100 * MIN_TAU_REL:g} % (spread τ {self._spread_pct()})"
        else:
            said = "they agree"
        return f"one {scale} across the targets ({', '.join(self.per_term)}): Cochran's Q p = {self.p:.2g}: {said}"

    def to_dict(self) -> dict:
        return {"role": self.role, "per_term": {k: list(v) for k, v in self.per_term.items()},
                "p": self.p, "tau": self.tau, "constant": self.constant, "mean": self.mean}

    @classmethod
    def from_dict(cls, d: Mapping) -> "SharedConstant":
        num = lambda v: math.nan if v is None else float(v)   # noqa: E731 - JSON null: a non-finite number
        return cls(str(d["role"]), {str(k): tuple(num(x) for x in v) for k, v in d["per_term"].items()},
                   num(d["p"]), num(d["tau"]), bool(d["constant"]), num(d.get("mean")))


def across_targets(terms: Mapping[str, Mapping[str, tuple[float, float, float]]]) -> dict[str, SharedConstant]:
    """{role: :class:`SharedConstant`} for the roles of :data:`SHARED_ROLES` in ``terms``
    ({role: {term label: (value, low, high)}}, each term's fitted scale and 95 % interval), with
    Holm over the roles that have at least two terms."""
    tested, ps = {}, {}
    for role in SHARED_ROLES:
        per = {lab: tuple(map(float, v)) for lab, v in terms.get(role, {}).items()
               if all(math.isfinite(float(x)) for x in v)}
        if len(per) < 2:
            continue
        h = heterogeneity([v[0] for v in per.values()], [se_of_interval(v[1], v[2]) for v in per.values()])
        if not math.isfinite(h["p"]):       # fewer than two terms with a spread: nothing to test
            continue
        tested[role], ps[role] = (per, h), h["p"]
    flags = holm_flags(ps)
    return {role: SharedConstant(role, per, h["p"], h["tau"], not moved(flags[role], h["tau"], h["mean"]), h["mean"])
            for role, (per, h) in tested.items()}
