"""The ladder of one target: the rungs from the empirical model as given to the final model, and
the guards that decide which rung a user gets.

Rungs, bottom to top: the empirical model as given; the prior refit; + the input offset (when
one was chosen); + each folded effect; the FINAL model (the physical rung, or the best SNGP run's
evolved terms added to it when they survive the guards and the calibrated block test). Every
rung is a :class:`Rung`: errors on the training rows, their validation blocks and the test
rows, the fitted terms with 95 % block-bootstrap :class:`Interval` s, and what was held or hit a
physical bound. The guards' tally is a :class:`GuardReport`.

Every choice uses TRAINING rows only (blocks of :mod:`droneid.dataset.validation`, the robust bounded
fits of :mod:`droneid.fitting.terms`, the rule of :mod:`droneid.fitting.decide`); test rows are measured for the
report and never looked at. Errors are RMSEs in the target's units (m/s² for v̇).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from droneid.core.constraint_samples import constraint_rmse
from droneid.dataset.data import Dataset
from droneid.fitting.constancy import Constancy
from droneid.fitting.flight_conditions import explained
from droneid.fitting.decide import decide
from droneid.errors import ConfigError, DataError
from droneid.core.expressions import evaluate_expr, round_expr, symbol, to_text
from droneid.fitting.closed_form import IdentifiedModel
from droneid.core.numerics import rmse, to_float
from droneid.fitting.physics_guard import ACCELERATION, guard_terms
from droneid.core.text import display_term
from droneid.identify.search import run_seeds
from droneid.sngp.model import SymbolicModel
from droneid.core.targets import velocity_of
from droneid.fitting.terms import (TermModel, constancy_of, defined_samples, drag_slope, drop_negligible, physical_fit,
                    plausible, prior_terms, trim_terms)
from droneid.dataset.validation import time_blocks, validation_blocks
from droneid.planning.plan import OFFSET_GRID_S
from priors.effect_catalogue.attitude_delay import attitude_rate

if TYPE_CHECKING:
    from droneid.identify.problem import TargetProblem
    from droneid.identify.search import RunRecord

__all__ = ["Interval", "Rung", "GuardReport", "rung", "physical_rungs", "final_rung", "bootstrap_blocks",
           "fitted_thrust", "evolved_labels", "physics_context", "trivial_errors", "TERM_ALPHA"]

#: family-wise level of keeping evolved terms (Bonferroni over the runs; :mod:`droneid.fitting.decide`)
TERM_ALPHA = 0.01


@dataclass(frozen=True)
class Interval:
    """A 95 % interval of a fitted coefficient (block bootstrap over the training flights' time
    blocks), in the coefficient's units (a scale on a prior term: 1 = nominal)."""
    low: float
    high: float

    def to_list(self) -> list:
        return [self.low, self.high]

    @classmethod
    def of(cls, pair) -> "Interval":
        lo, hi = pair
        return cls(to_float(lo), to_float(hi))


@dataclass(frozen=True)
class Rung:
    """One rung of the ladder.

    name : ``empirical``, ``refit``, ``delay``, ``effect:<name>`` or ``final``
    description : what the rung adds, one line
    rmse_train, rmse_validation, rmse_test : errors on the training rows, on their validation
        blocks (each block predicted by the same terms refit without it; the training error for a
        model with nothing fitted) and on the test rows (NaN without test rows)
    constraint_rmse_test : e_c on the test draw of constraint samples (NaN without a set)
    terms : {label: fitted coefficient}; prior terms as ``⟨name⟩`` (a scale, 1 = nominal)
    intercept : the equation's constant (fitted plus known physics: gravity), None when nothing
        was fitted
    model : the rung as an :class:`~droneid.fitting.closed_form.IdentifiedModel` (what predict applies)
    intervals : {label: Interval}; held : {label: value held at}, coefficients the data cannot
        identify; at_bound : {label: value}, coefficients the data pull to a physical bound
    evidence : sentences saying why (holds, bounds)
    pred_test : the rung's prediction on the test rows (memory only, not in result.json)
    constancy : {label: :class:`~droneid.fitting.constancy.Constancy`}, each vehicle constant's values
        per training flight (or stretch of one flight) and its constancy test
    """
    name: str
    description: str
    rmse_train: float
    rmse_validation: float
    rmse_test: float
    constraint_rmse_test: float
    terms: Mapping[str, float]
    intercept: float | None
    model: IdentifiedModel
    intervals: Mapping[str, Interval] = field(default_factory=dict)
    held: Mapping[str, float] = field(default_factory=dict)
    at_bound: Mapping[str, float] = field(default_factory=dict)
    evidence: tuple[str, ...] = ()
    pred_test: np.ndarray | None = field(default=None, repr=False, compare=False)
    constancy: Mapping[str, Constancy] = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The rung as ``result.json`` holds it (``targets.<t>.ladder[i]``; no ``pred_test``)."""
        return {"name": self.name, "description": self.description, "rmse_train": self.rmse_train,
                "rmse_validation": self.rmse_validation, "rmse_test": self.rmse_test,
                "constraint_rmse_test": self.constraint_rmse_test, "terms": dict(self.terms),
                "intercept": self.intercept, "model": self.model.to_dict(),
                "intervals": {k: v.to_list() for k, v in self.intervals.items()},
                "held": dict(self.held), "at_bound": dict(self.at_bound), "evidence": list(self.evidence),
                "constancy": {k: v.to_dict() for k, v in self.constancy.items()}}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Rung":
        """Read back :meth:`to_dict` (DataError for a malformed rung)."""
        try:
            return cls(str(d["name"]), str(d["description"]), to_float(d["rmse_train"]),
                       to_float(d["rmse_validation"]), to_float(d["rmse_test"]),
                       to_float(d["constraint_rmse_test"]), {str(k): float(v) for k, v in d["terms"].items()},
                       None if d["intercept"] is None else float(d["intercept"]),
                       IdentifiedModel.from_dict(d["model"]),
                       {str(k): Interval.of(v) for k, v in d["intervals"].items()},
                       {str(k): float(v) for k, v in d["held"].items()},
                       {str(k): float(v) for k, v in d["at_bound"].items()},
                       tuple(str(e) for e in d["evidence"]), None,
                       # results written before the constancy test have none
                       {str(k): Constancy.from_dict(v) for k, v in (d["constancy"] if "constancy" in d else {}).items()})
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise DataError(f"not a ladder rung: {type(exc).__name__} {exc}") from None


@dataclass(frozen=True)
class GuardReport:
    """What the trust guards did with the SNGP runs of one target (:func:`final_rung`).

    bound : the plausibility bound (± target units) on the training inputs' range ± 20 %
    candidates : runs whose evolved terms survived every guard
    implausible, no_evolved_term_left, constraints_broken, drag_not_monotone : runs rejected,
        by reason; dropped : one line per dropped term or rejected run
    constraint_limit : e_c limit of a candidate (None without a constraint set)
    drag_slope_limit : the largest ∂v̇/∂v a candidate may reach, 1/s (None without a velocity)
    decision : the block test's evidence for the best candidate (None without one)
    chosen_run : the run whose evolved terms are in the final model (0-based), or None
    best_evolved_validation : the best candidate's validation error when it was not kept
    """
    bound: float = math.nan
    candidates: int = 0
    implausible: int = 0
    no_evolved_term_left: int = 0
    constraints_broken: int = 0
    drag_not_monotone: int = 0
    dropped: tuple[str, ...] = ()
    constraint_limit: float | None = None
    drag_slope_limit: float | None = None
    decision: str | None = None
    chosen_run: int | None = None
    best_evolved_validation: float | None = None

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}

    @classmethod
    def from_dict(cls, d: Mapping) -> "GuardReport":
        known = set(cls.__dataclass_fields__)
        kw = {k: v for k, v in dict(d or {}).items() if k in known}
        if "dropped" in kw:
            kw["dropped"] = tuple(kw["dropped"] or ())
        if "bound" in kw:
            kw["bound"] = to_float(kw["bound"])
        return cls(**kw)


def _cs_columns(cs) -> dict:
    return {n: cs.X[:, i] for i, n in enumerate(cs.input_names)}


def _ec(pred_cs, cs) -> float:
    return float(constraint_rmse(pred_cs, cs)) if cs is not None else float("nan")


def bootstrap_blocks(ds: Dataset, **need) -> np.ndarray:
    """The time blocks the intervals resample and the block tests use
    (:func:`droneid.dataset.validation.time_blocks`: ~150 samples each; ``need``: family and alpha of a test)."""
    return time_blocks(ds.t, ds.flight, **need)


def rung(name: str, description: str, model, train: Dataset, test: Dataset, cs, *,
         blocks=None, fitted: bool = True, terms: dict | None = None, delays=None,
         alternatives: Sequence[tuple] = ()) -> Rung:
    """One rung of the ladder: a model (IdentifiedModel, or a TermModel: fitted here, robust and
    bounded, with 95 % block-bootstrap intervals and unidentifiable physical coefficients held at
    their nominal value, :func:`droneid.fitting.terms.physical_fit`) measured on the training rows
    (train; validation = blocked CV of the same terms refit without each block, or the training
    error for a model with nothing fitted), the test rows and the constraints. ``alternatives``:
    ((offset s, training Dataset, the training rows it shares), ...) the thrust inputs read at each
    other offset the data admit (:attr:`TargetProblem.train_at`): the intervals span the refits there."""
    tr_cols, te_cols = train.columns(), test.columns()
    evidence = None
    if isinstance(model, TermModel):
        alts = tuple((f"{1000 * d:+.0f} ms", ds.columns(), ds.y, same.columns(), same.y)
                     for d, ds, same in alternatives)
        evidence = physical_fit(model, tr_cols, train.y, bootstrap_blocks(train), flight=train.flight,
                                t=train.t, sources=train.sources, alternatives=alts)
        model = evidence.model
        p_tr, p_te = model.predict(tr_cols, len(train)), model.predict(te_cols, len(test))
        val = model.cv_rmse(tr_cols, train.y, blocks) if fitted and blocks is not None else rmse(p_tr, train.y)
        p_cs = model.predict(_cs_columns(cs), len(cs)) if cs is not None else None
        final = IdentifiedModel(train.target_name, model.expr(), dict(delays or {}), description)
        terms = terms if terms is not None else {lab: c for lab, c in zip(model.labels, model.coefs)}
        # the equation's constant: the fitted intercept plus the known physics no fit touches (gravity)
        intercept = model.intercept + (float(model.offset) if model.offset.is_number else 0.0)
    else:
        final = model
        p_tr, p_te = model.evaluate(tr_cols), model.evaluate(te_cols)
        val = rmse(p_tr, train.y)
        p_cs = model.evaluate(_cs_columns(cs)) if cs is not None else None
        intercept = None
    return Rung(name, description, rmse(p_tr, train.y), val, rmse(p_te, test.y),
                _ec(p_cs, cs) if p_cs is not None else float("nan"), dict(terms or {}), intercept, final,
                {k: Interval.of(v) for k, v in evidence.intervals.items()} if evidence else {},
                dict(evidence.held) if evidence else {}, dict(evidence.at_bound) if evidence else {},
                tuple(evidence.notes) if evidence else (), p_te, dict(evidence.constancy) if evidence else {})


#: the attitude alignment's bound (s) in :func:`per_flight_condition_lead`: the thrust offset grid's reach
ALIGN_MAX_S = max(OFFSET_GRID_S)


def per_flight_condition_lead(p: TargetProblem, final: Rung) -> str:
    """One sentence testing the simplest flight conditions behind vehicle constants that move
    between flights ("" when none moves, or with one training flight): the final physical model
    (its held coefficients kept) refitted on each flight alone with one condition of that
    flight's own, by the same constancy test (:func:`droneid.fitting.terms.constancy_of`), and
    read by :func:`droneid.fitting.flight_conditions.explained` (a constant the refit holds only because
    the condition made every flight's estimate too uncertain is "not told apart"):

    * a constant acceleration (what a wind that differs between flights does to a drag term,
      ``k_D·w``);
    * the attitude read at a time alignment of its own, ``|τ|`` ≤ :data:`ALIGN_MAX_S` s (a clock
      offset of the attitude stream: the terms' change with the attitude's rate, weighted by
      their fitted coefficients, :func:`priors.effect_catalogue.attitude_delay.attitude_rate`, as
      a column whose coefficient is τ; each flight's τ is reported). On a path that brakes at
      corners the tilt's rate follows the velocity, so a few ms of alignment move a drag term.

    A constant that holds then is moved by something per flight, not by the vehicle."""
    bad = [lab for lab, c in final.constancy.items() if c.constant is False and c.unit == "flight"]
    if not bad or p.plan is None:
        return ""
    tm = _physical_model(p, p.priors3)
    lo, hi = list(tm.lo), list(tm.hi)
    for i, lab in enumerate(tm.labels):
        if lab in final.held:
            lo[i] = hi[i] = final.held[lab]
    held = replace(tm, lo=tuple(lo), hi=tuple(hi))
    which = [tm.labels.index(lab) for lab in bad if lab in tm.labels]
    if not which:
        return ""
    free = sorted({tm.labels.index(lab) for lab in final.constancy if lab in tm.labels} | set(which))
    cols, tr = p.train.columns(), p.train
    out = [_refit_lead(held, cols, tr, np.ones(len(tr), bool), which, free, final.constancy,
                       "with a constant acceleration of its own on each training flight (what a wind that "
                       "differs between flights does to a drag term, k_D·w)", intercept=True)]
    weights = [_fitted_scale(final, lab) for lab in tm.labels]
    rate = attitude_rate(tm.terms, cols, tr.t, tr.flight, weights=weights)
    if rate is not None:
        name = "attitude_alignment_s"
        aligned = replace(held, terms=(*held.terms, symbol(name)), labels=(*held.labels, "attitude alignment"),
                          lo=(*held.lo, -ALIGN_MAX_S), hi=(*held.hi, ALIGN_MAX_S))
        ok = np.isfinite(rate)
        left = f"; {int(np.sum(~ok))} rows without an attitude rate left out" if not ok.all() else ""
        out.append(_refit_lead(aligned, {**cols, name: rate}, tr, ok, which, free, final.constancy,
                               f"with the attitude read at a time alignment of its own on each training flight "
                               f"(|τ| ≤ {1000 * ALIGN_MAX_S:.0f} ms: what a clock offset of the attitude stream "
                               f"does{left})", describe=len(held.terms)))
    return "; ".join(out)


def _fitted_scale(final: Rung, label: str) -> float:
    """The final rung's coefficient of the physical term ``label``: its own, held, or the scale of
    the tied group it joined (``⟨a + b⟩``); 0 when the rung dropped it."""
    if label in final.terms:
        return float(final.terms[label])
    if label in final.held:
        return float(final.held[label])
    inner = label.strip("⟨⟩")
    tied = [v for lab, v in final.terms.items() if inner in lab.strip("⟨⟩").split(" + ")]
    return float(tied[0]) if tied else 0.0


def _refit_lead(model: TermModel, cols, tr: Dataset, rows: np.ndarray, which, free, before, what: str, *,
                intercept: bool = False, describe: int | None = None) -> str:
    """One condition's part of :func:`per_flight_condition_lead`: ``model`` (with the intercept
    free when ``intercept``: an acceleration per flight) refit on each training flight's
    ``rows``, each constant ``which`` read by :func:`droneid.fitting.flight_conditions.explained` against
    its record ``before``, and the per-flight values of the condition's coefficient
    ``describe`` (an alignment in s, said in ms)."""
    if intercept:
        model = replace(model, intercept_bounds=(-math.inf, math.inf))
    sub = {n: np.asarray(v)[rows] for n, v in cols.items()}
    res = constancy_of(model, sub, tr.y[rows], which, tr.flight[rows], tr.t[rows], tr.sources,
                       free=free, describe=() if describe is None else (describe,))
    said = explained({lab: before[lab] for lab in res if lab in before}, res)
    per = res[model.labels[describe]].per_unit if describe is not None and model.labels[describe] in res else {}
    pinned = [f for f, (v, _, _) in per.items() if abs(v) >= 0.999 * ALIGN_MAX_S]
    parts = []
    for lab, (word, growth) in said.items():
        if word == "constant" and pinned:      # a coefficient at its bound has no spread to lend the others
            word, why = "not told apart", f" ({', '.join(pinned)} at the alignment's bound)"
        elif word == "not told apart" and math.isfinite(growth):
            why = (f" (with it free each flight's estimate is {growth:.2g}x as uncertain: too uncertain to show "
                   f"the spread it had)")
        else:
            why = ""
        p_text = f" p = {res[lab].p:.2g}" if math.isfinite(res[lab].p) else ""
        parts.append(f"{lab}{p_text}: {word}{why}")
    if per:
        parts.append("each flight's alignment " + ", ".join(
            f"{f} {round(1000 * v):+d} ms" + (" (at its bound)" if f in pinned else "") for f, (v, _, _) in per.items()
            if math.isfinite(v)))
    return what + ", " + "; ".join(parts)


def _physical_model(p: TargetProblem, features) -> TermModel:
    """The unfitted physical model of ``p`` over ``features`` (prior terms and effects): bounds,
    gravity and intercept bounds as the prior declares them."""
    if p.plan is None:
        return TermModel.of(features)
    return prior_terms(p.plan.prior, p.target, features)


def physical_rungs(p: TargetProblem, empirical: IdentifiedModel, undelayed: tuple | None = None) -> tuple[Rung, ...]:
    """The ladder's physical rungs: ``empirical`` (the user's model as given), the prior refit
    (without the input offset: on ``undelayed`` = (train, test) when one was chosen), + the
    offset, + each folded effect."""
    plan = p.plan
    cs = p.cs_test
    ladder = [rung("empirical", empirical.description, empirical, p.train, p.test, cs, fitted=False)]
    base = p.priors3[:p.n_base]
    prior_name = getattr(plan.prior, "name", "prior") if plan else "prior"
    tm = _physical_model(p, base)
    if plan is not None and plan.delays_s and undelayed is not None:
        tr0, te0 = undelayed
        b0, _ = validation_blocks(tr0.t, tr0.flight)
        ladder.append(rung("refit", f"{prior_name} prior refit", tm, tr0, te0, cs, blocks=b0))
        d = next(iter(plan.delays_s.values()))
        what = (f"+ thrust inputs delayed by {1000 * d:.0f} ms" if d > 0 else
                f"+ thrust stream clock corrected (read {1000 * -d:.0f} ms later)")
        ladder.append(rung("delay", what, tm, p.train, p.test, cs, blocks=p.blocks, delays=plan.delays_s,
                           alternatives=p.train_at))
    else:
        ladder.append(rung("refit", f"{prior_name} prior refit", tm, p.train, p.test, cs, blocks=p.blocks,
                           delays=plan.delays_s if plan else None, alternatives=p.train_at))
    for e in (plan.effects if plan else ()):
        feats = e.features.get(p.target, ())
        if not feats:
            continue
        base = base + tuple(feats)
        tm = _physical_model(p, base)
        ladder.append(rung(f"effect:{e.effect}", f"+ {e.effect} ({e.physical})",
                           tm, p.train, p.test, cs, blocks=p.blocks, delays=plan.delays_s, alternatives=p.train_at))
    return tuple(ladder)


def fitted_thrust(p: TargetProblem, terms: Mapping[str, float]) -> float | None:
    """Median over the training rows of the fitted specific thrust (m/s², the thrust terms'
    fitted scales times their magnitudes, without the direction), or None for priors without
    thrust magnitudes (:meth:`priors.base.PriorModel.fitted_thrust`)."""
    if p.plan is None:
        return None
    lift = p.plan.prior.fitted_thrust(p.target, {k.strip("⟨⟩"): v for k, v in terms.items()},
                                      p.train.columns(), len(p.train))
    return float(np.median(lift)) if lift is not None and len(lift) else None


def evolved_labels(raw: Sequence[sp.Expr], prior_labels: Mapping[str, str]) -> tuple[list, list[str]]:
    """(terms, labels) of evolved terms as the equation shows them: a term that reads with a
    leading minus (``-rpm2``) is negated, so its label has no sign of its own and the fitted
    coefficient carries it (never ``-1.9e-05·-rpm2``); prior symbols read as ⟨name⟩."""
    terms, labels = [], []
    for t in raw:
        txt, neg = display_term(to_text(round_expr(t, 4)), dict(prior_labels))
        terms.append(-t if neg else t)
        labels.append(txt)
    return terms, labels


def trivial_errors(y_train: np.ndarray, blocks: np.ndarray | None, y_test: np.ndarray) -> dict:
    """{"zero": RMSE, "the training mean": RMSE} of predicting no model at all (m/s² for v̇),
    measured as the verdict measures the models: on the test rows when there are any (the mean
    of the training rows), else on the training rows' validation blocks (each block predicted by
    the mean of the others; zero needs no fit)."""
    y_train, y_test = np.asarray(y_train, float), np.asarray(y_test, float)
    if y_test.size:
        return {"zero": rmse(np.zeros_like(y_test), y_test),
                "the training mean": rmse(np.full_like(y_test, float(np.mean(y_train))), y_test)}
    pred = np.full_like(y_train, float(np.mean(y_train))) if y_train.size else y_train
    if blocks is not None and y_train.size:
        for b in np.unique(blocks):
            out = blocks != b
            if out.any():
                pred[blocks == b] = float(np.mean(y_train[out]))
    return {"zero": rmse(np.zeros_like(y_train), y_train), "the training mean": rmse(pred, y_train)}


def physics_context(p: TargetProblem) -> dict:
    """The keywords of :func:`droneid.fitting.physics_guard.term_problem` for ``p``'s evolved terms:
    prior feature symbols are accelerations; a single-motor term is allowed only when the
    diagnosis folded the per-motor thrust effect; height only when ground effect was testable
    (the flights spend time near the ground)."""
    effects = {e.effect for e in (p.plan.effects if p.plan else ())}
    untestable = (p.plan.diagnosis.get("untestable") or {}) if p.plan else {}
    height = p.plan is not None and bool(p.plan.diagnosis) and "ground_effect" not in untestable
    return {"per_motor": "motor_thrust" in effects, "height": height}


def final_rung(p: TargetProblem, cfg, done: Sequence[RunRecord]) -> tuple[Rung, GuardReport]:
    """(final rung, guard report): the best evolved model that survives the trust guards, or the
    physical rung (prior + delay + effects) when none beats it on TRAINING validation blocks by
    the calibrated block test of :mod:`droneid.fitting.decide` (held-out errors of both, time blocks,
    α = :data:`TERM_ALPHA` Bonferroni over the runs, at least ``cfg.margin`` lower error).

    Guards, in order, per run: evolved terms that no vehicle model may hold (one motor's speed
    alone, absolute position, mixed units: :func:`droneid.fitting.physics_guard.term_problem`) are
    dropped; the rest are added to ALL prior and effect features; near-duplicate columns (cancelling pairs) are merged and evolved terms that do not
    lower the blocked-CV error by 1 % are dropped (:func:`droneid.fitting.terms.trim_terms`); the
    model must stay within ±(2·max|y_train| + g) on a grid spanning the training inputs ± 20 %
    (:func:`droneid.fitting.terms.plausible`); its constraint error on a training draw of the constraint
    samples must stay below max(γ, 1.1 x the physical rung's); drag must grow with speed: along
    its own-axis velocity (±1.2 x the training speed, other inputs at 50 flown states) the
    model's slope may not exceed the physical rung's (or 0) by more than 0.05 1/s. The survivor
    with the lowest CV error replaces the physical rung only if it passes that test.
    ``cfg``: the identify config (seed, margin, γ, constraint samples)."""
    phys = p.ladder[-1]
    delays = p.plan.delays_s if p.plan else {}
    cols, y = p.train.columns(), p.train.y
    phys_model = _physical_model(p, p.priors3)
    phys_tm = phys_model.fit(cols, y)      # the physical rung refit on the training rows, once
    base = phys_model.terms
    bound = 2.0 * float(np.max(np.abs(y))) + 9.81
    ranges = {n: (float(np.min(p.train.X[:, i])), float(np.max(p.train.X[:, i])))
              for i, n in enumerate(p.train.input_names)}
    g = {"bound": bound, "implausible": 0, "no_evolved_term_left": 0, "constraints_broken": 0,
         "drag_not_monotone": 0, "candidates": 0}
    dropped: list[str] = []
    cset = p.constraint_set if p.constraint_set is not None else p.eval_constraint_set
    cs_sel, ec_limit = None, math.inf
    if cset is not None:  # a training draw of constraint samples (not the e_c^test draw)
        cs_sel, _ = defined_samples(cset.sample(list(p.train.input_names), n_per_constraint=cfg.n_constraint_samples,
                                                seed=run_seeds(cfg.seed + 1, 0)[0]), p.priors3)
        ec_phys = _ec(phys_tm.predict(_cs_columns(cs_sel), len(cs_sel)), cs_sel)
        ec_limit = max(cfg.gamma, 1.1 * ec_phys)
        g["constraint_limit"] = ec_limit
    vel = velocity_of(p.target)
    slope_limit, rows, v_max = math.inf, {}, 0.0
    if vel in p.train.input_names:
        pick = np.random.default_rng(cfg.seed).choice(len(p.train), size=min(50, len(p.train)), replace=False)
        rows = {n: p.train.X[pick, j] for j, n in enumerate(p.train.input_names)}
        v_max = 1.2 * float(np.max(np.abs(cols[vel])))
        phys_slope = drag_slope(phys_tm.expr(), vel, rows, v_max)
        slope_limit = max(phys_slope, 0.0) + 0.05
        g["drag_slope_limit"] = slope_limit
    physics = physics_context(p)
    best = None
    for i, r in enumerate(done):
        try:
            m = SymbolicModel.from_dict(r.model)
        except (ConfigError, DataError, KeyError, TypeError):
            continue
        prior_syms = {symbol(k) for k in m.priors}
        subs = {symbol(k): v for k, v in m.priors.items()}
        env = {**cols, **{k: evaluate_expr(v, cols, len(y)) for k, v in m.priors.items()}}
        raw = [drop_negligible(t, env, len(y)) for t in m.terms if t not in prior_syms]
        raw, labels = evolved_labels(raw, {k: m.prior_labels.get(k, k) for k in m.priors})
        keep, refused = guard_terms(raw, labels, p.train.input_names, **physics,
                                    symbols=dict.fromkeys(m.priors, ACCELERATION))
        dropped.extend(f"run {i + 1}: {n}" for n in refused)
        raw, labels = [raw[k] for k in keep], [labels[k] for k in keep]
        evolved = [t.xreplace(subs) for t in raw]
        if not evolved:
            g["no_evolved_term_left"] += 1
            continue
        tm = phys_model.extended(evolved, tuple(labels))
        sizes = [0] * len(base) + [int(sp.count_ops(t)) for t in raw]
        trimmed, notes = trim_terms(tm, cols, y, p.blocks, keep_first=len(base), sizes=sizes)
        dropped.extend(f"run {i + 1}: {n}" for n in notes)
        if len(trimmed.terms) == len(base):
            g["no_evolved_term_left"] += 1
            continue
        pl = plausible(trimmed.expr(), ranges, bound)
        if not pl.ok:
            g["implausible"] += 1
            dropped.append(f"run {i + 1}: rejected, {pl.note}")
            continue
        if cs_sel is not None:
            ec = _ec(trimmed.predict(_cs_columns(cs_sel), len(cs_sel)), cs_sel)
            if not ec <= ec_limit:
                g["constraints_broken"] += 1
                dropped.append(f"run {i + 1}: rejected, constraint error {ec:.3g} > {ec_limit:.3g}")
                continue
        if rows:
            slope = drag_slope(trimmed.expr(), vel, rows, v_max)
            if not slope <= slope_limit:
                g["drag_not_monotone"] += 1
                dropped.append(f"run {i + 1}: rejected, ∂{p.target}/∂{vel} reaches {slope:.3g} 1/s "
                               f"within ±{v_max:.3g} m/s (drag must grow with speed)")
                continue
        cv = trimmed.cv_rmse(cols, y, p.blocks)
        g["candidates"] += 1
        if best is None or cv < best[0]:
            best = (cv, i, trimmed)
    decision = None
    if best is not None:   # the calibrated rule of droneid.fitting.decide: held-out errors, time blocks, Bonferroni over the runs
        err0 = y - phys_model.cv_predictions(cols, y, p.blocks)
        err1 = y - best[2].cv_predictions(cols, y, p.blocks)
        decision = decide(err0, err1, bootstrap_blocks(p.train, family=max(len(done), 1), alpha=TERM_ALPHA),
                          alpha=TERM_ALPHA, family_size=max(len(done), 1),
                          min_effect_pct=100 * cfg.margin, what=f"evolved terms of run {best[1] + 1}")
        g["decision"] = decision.evidence
    if decision is not None and decision.accepted:
        cv, i, tm = best
        n_ev = len(tm.terms) - len(base)
        final = rung("final", f"+ {n_ev} evolved term{'s' * (n_ev > 1)} (run {i + 1})", tm, p.train, p.test,
                     p.cs_test, blocks=p.blocks, delays=delays, alternatives=p.train_at)
        g["chosen_run"] = i
    else:
        final = replace(phys, name="final", description=f"= the rung above (no evolved term passed the block "
                        f"test: {100 * cfg.margin:.0f} % lower held-out error at α = {TERM_ALPHA:g})")
        if best is not None:
            g["best_evolved_validation"] = best[0]
    return final, GuardReport(dropped=tuple(dropped), **g)
