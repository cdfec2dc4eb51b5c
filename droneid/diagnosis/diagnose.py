"""Diagnosis: find what a prior model lacks, in physical terms, with out-of-sample evidence.

From flights (:func:`diagnose`) the diagnosis runs under the plan identify makes
(:mod:`droneid.planning.plan`: :func:`~droneid.planning.plan.plan_inputs` chooses the prior, the thrust curve of a
command-driven vehicle and the thrust inputs' offset; :func:`~droneid.planning.plan.diagnosis_datasets`
builds the datasets of that plan), so diagnose and identify take the same decisions on the same
flights; identify's plan (:func:`plan_identification`) is that plan with the diagnosed effects
folded in. Pipeline (:func:`diagnose_datasets` from Datasets):

1. Fit the prior as given (every feature weight 1) and refit it by least squares WITHOUT an
   intercept (a free intercept would absorb wind and attitude biases), jointly for all targets;
   the residual is what the refit prior leaves.
2. Score every testable effect of the catalogue (:mod:`priors.effects`) by BLOCKED
   cross-validation: each training flight is cut into ``n_blocks`` contiguous time blocks; the
   model with and without the effect is fitted on all blocks but one and predicts the held-out
   one. Effects are fitted jointly over the targets: a parameter shared by v̇x and v̇y (quadratic
   drag c, attitude biases, delay τ) is one coefficient.
3. Add the best effect only if the one decision rule accepts it (:func:`droneid.fitting.decide.decide`):
   a one-sided paired sign-flip test on the per-block relative differences of held-out squared
   error with and without it, at Holm's ``alpha / (m − k + 1)`` (m: every candidate the diagnosis
   may try, singles and pairs; k: the step), a held-out RMSE reduction of at least
   ``min_rel_improvement``, and physically possible fitted values (``Effect.plausible_fn``). After
   the last step every added effect is judged again with all the others in (:func:`_backward`). When no single effect passes but the best one gains at least
   ``pair_min_gain`` (effects that overlap: each alone explains only part, unevenly across
   blocks), the pairs of the ``pair_top`` best candidates are judged JOINTLY by the same rule; a
   pair is added (one step, ``"tested_jointly"``) only if it passes and beats each of its members
   alone by ``min_rel_improvement``. Refit and repeat; otherwise stop: "no further effect is
   detectable from these signals". Every candidate's evidence, accepted or rejected, is kept.
   An effect is tried only when its preconditions hold on the training data (``Effect.data_fn``:
   e.g. ground effect needs time near the ground); otherwise it is untestable, with the reason.
4. An open-ended SNGP search on the remaining residual over the available causal signals catches
   what the catalogue lacks; its term is reported only if it passes the same held-out rule
   (interleaved-block 2-fold CV).

This module is the orchestration (the steps above, the result's summaries). The pieces live in
:mod:`droneid.diagnosis.result` (settings and result as data), :mod:`droneid.diagnosis.effect_model` (the
stacked least-squares model, held-out evidence, scoring and re-judging of effects) and
:mod:`droneid.diagnosis.residual_search` (step 4); the rule itself in :mod:`droneid.fitting.decide`.

THE TEST FLIGHTS NEVER DECIDE: selection, coefficients and the conclusion use the training
flights only (the same result with and without test flights); test errors are reported.
Causal inputs only: measured derivatives (IMU ``ax ay az``, differenced ``vz_dot``) are neither
effect features nor open-ended signals unless ``allow_measured_derivatives``, and then the
result says the model cannot be simulated (``simulable`` False when one is used).

Effects whose signals are missing are reported UNTESTABLE, never absent; effects that make no
sense for the prior or target are NOT APPLICABLE (e.g. thrust_variation with rotor-thrust).
``final_effects[i]["features"]`` gives each foldable effect's features as sympy expressions over
canonical signals with constants fixed from training, ready to join the prior's features.
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import asdict, replace

import math

import numpy as np

from priors.effects import CATALOGUE, is_measured_derivative
from priors.registry import resolve_prior

from droneid.dataset.data import Dataset
from droneid.logs.flight import distinct_flights
from droneid.fitting.decide import decide
from droneid.diagnosis.result import (NO_FURTHER, DiagnoseConfig, DiagnosisResult, evidence_of,
                               fold_into_prior, folded_feature, held_to_size, with_test_errors)
from droneid.diagnosis.effect_model import (EffectModel, air_jacobians, diagnose_blocks, drop_stand_ins, fold_features,
                           linear_drag_of, make_part, physical_terms, prior_terms,
                           refine_contexts, score_candidates, strip_effect_id, uses_derivative)
from droneid.errors import ConfigError, DataError, did_you_mean
from droneid.planning.plan import Effect, diagnosis_datasets, plan_inputs, resolve_plan_prior
from droneid.planning.settings import IdentifyConfig
from droneid.dataset.suitability import check_prior_data
from droneid.dataset.validation import block_ids
from droneid.core.numerics import rmse
from droneid.diagnosis.residual_search import equation_signals, search_residuals
from droneid.core.targets import targets_for

log = logging.getLogger(__name__)

__all__ = ["DiagnoseConfig", "DiagnosisResult", "diagnose", "diagnose_datasets", "evidence_of",
           "block_ids", "NO_FURTHER", "fold_into_prior", "diagnose_plan", "plan_identification",
           "diagnose_blocks"]

def diagnose(train_flights, test_flights=None, prior="tilt-drag", targets=None, *,
             config: DiagnoseConfig | None = None, user_effects=None, progress=None) -> DiagnosisResult:
    """Diagnose on flights under the plan identify would make: :func:`diagnose_plan` (the prior,
    its thrust curve, the thrust inputs' offset), the datasets of that plan
    (:func:`droneid.planning.plan.diagnosis_datasets`), then :func:`diagnose_datasets`. The plan is in the
    result (``plan``: its lines and record, as identify prints and records them).

    ``prior``: a PriorModel, a name (``file.toml:name`` for user priors) or ``"auto"`` (the
    prior identify chooses: :func:`droneid.dataset.suitability.prior_for_flights`). ``targets`` None:
    the prior's targets among vx_dot, vy_dot, vz_dot.
    """
    cfg = (config or DiagnoseConfig()).validate()
    _select_effects(user_effects, cfg.effects)      # an unknown effect id is refused before any work
    train_flights, test_flights, repeated = distinct_flights(train_flights, test_flights or ())
    icfg = _plan_config(prior, targets, cfg)
    pr, _ = resolve_plan_prior(icfg, train_flights)
    tg = targets_for(pr, icfg.targets)
    check_prior_data(train_flights, pr, tg, cfg.ts, "training")
    if test_flights:
        check_prior_data(test_flights, pr, tg, cfg.ts, "test")
    plan = plan_inputs(train_flights, icfg, progress)
    train, decided = diagnosis_datasets(plan, plan.aligned(train_flights), icfg)
    test = diagnosis_datasets(plan, test_flights, icfg)[0] if test_flights else None
    res = diagnose_datasets(train, test, prior=plan.prior, prior_label=_prior_label(prior, plan), config=cfg,
                            user_effects=user_effects, progress=progress, decided=decided)
    return replace(res, plan={"lines": [*repeated, *plan.lines()], **plan.record()})


def diagnose_plan(train_flights, prior="auto", targets=None, config: DiagnoseConfig | None = None,
                  progress=None):
    """The :class:`~droneid.planning.plan.Plan` :func:`diagnose` works under: :func:`droneid.planning.plan.plan_inputs`
    with identify's settings for this prior, these targets, this grid and differentiator (offset
    chosen, effects left to the diagnosis): the same flights give identify's prior, thrust curve
    and offset."""
    cfg = (config or DiagnoseConfig()).validate()
    return plan_inputs(list(train_flights), _plan_config(prior, targets, cfg), progress)


def _plan_config(prior, targets, cfg: DiagnoseConfig) -> IdentifyConfig:
    """The identify settings of the shared plan (:func:`droneid.planning.plan.plan_inputs`)."""
    return replace(IdentifyConfig(), prior=prior, targets=tuple(targets) if targets else None,
                   ts=cfg.ts, method=cfg.method, delays="auto", effects="auto").validated()


def _prior_label(spec, plan) -> str:
    """The prior as the report names it: its name, and for ``auto`` (or rotor-thrust) its thrust
    source and why."""
    pr = plan.prior
    if not isinstance(spec, str):
        return getattr(spec, "name", type(spec).__name__)
    if spec not in ("auto", "rotor-thrust"):
        return spec
    args = ", ".join(f"{k}={pr.params[k]}" for k in ("source", "motors") if k in pr.params)
    return f"{pr.name}" + (f" ({args})" if args else "") + f": {plan.prior_reason}"


def plan_identification(train_flights, cfg, progress: Callable | None = None, cuts: dict | None = None):
    """Identify's :class:`~droneid.planning.plan.Plan`: :func:`droneid.planning.plan.plan_inputs` (prior, thrust
    curve, offset) and, with ``cfg.effects`` ``"auto"``, the diagnosis on the datasets diagnose
    judges (:func:`droneid.planning.plan.diagnosis_datasets`, its open-ended search off: identify's SNGP
    runs are the open-ended search), every effect that passes folded into the prior features
    (``cuts``: {flight index: time s} where a held-out test block starts, never seen here)."""
    plan = plan_inputs(train_flights, cfg, progress, cuts)
    if cfg.effects != "auto":
        return plan
    train, decided = diagnosis_datasets(plan, plan.aligned(train_flights), cfg, cuts)
    try:
        res = diagnose_datasets(train, None, prior=plan.prior, decided=decided,
                                config=DiagnoseConfig(ts=cfg.ts, method=cfg.method, generations=0))
    except (ConfigError, DataError, TypeError) as exc:
        return replace(plan, notes=(*plan.notes, f"diagnosis skipped: {exc}"))
    folded, notes = [], [f"diagnosis on the training flights: {res.conclusion}"]
    for fe in res.final_effects:
        feats = fe.get("features")
        if fe.get("foldable") and feats:
            folded.append(Effect(fe["effect"], fe.get("physical", ""),
                                 {t: tuple(folded_feature(fe["effect"], d, fe.get("physical", ""))
                                           for d in feats.get(t, ())) for t in plan.targets}))
        else:
            notes.append(f"effect {fe['effect']} ({fe.get('physical', '')}) not folded into the model: "
                         f"{fe.get('reason') or 'not foldable into a model of states and inputs'}")
    summary = {"effects_added": list(res.effects_added), "conclusion": res.conclusion,
               "untestable": dict(res.untestable), "not_detected": list(res.not_detected)}
    return replace(plan, effects=tuple(folded), diagnosis=summary, notes=(*plan.notes, *notes))


def _select_effects(user_effects, only, decided=()) -> dict:
    """The catalogue plus user effects, restricted to ``only`` (ids) when given, without the
    ``decided`` ones (another stage of the plan decided them)."""
    effects = dict(CATALOGUE)
    for e in (user_effects.values() if isinstance(user_effects, Mapping) else user_effects or ()):
        effects[e.id] = e
    if only is not None:
        for eid in only:
            if eid not in effects:
                raise ConfigError(f"unknown effect '{eid}'{did_you_mean(eid, effects)}; known: {', '.join(effects)}")
        effects = {k: v for k, v in effects.items() if k in only}
    return {k: v for k, v in effects.items() if k not in decided}


def _testability(effects, tr_parts, targets, allow_derivatives) -> tuple[list, dict, dict]:
    """(testable effects, {id: why untestable}, {id: why not applicable}), from the TRAINING
    parts only: an effect is testable when every training part it applies to has its signals."""
    untestable, not_applicable, testable = {}, {}, []
    for eid, e in effects.items():
        applicable, why_not = [], []
        for p in tr_parts:
            why = e.not_applicable(p.ctx)
            (why_not if why else applicable).append(why or p)
        if not applicable:
            prior_why = sorted({w for w in why_not if not w.startswith("does not apply to")})
            not_applicable[eid] = "; ".join(prior_why) or \
                f"applies only to {', '.join(getattr(e, 'targets', ()) or ('other targets',))}"
            continue
        miss = sorted({m for p in applicable for m in e.missing(p.ctx.available())})
        weak = sorted({w for p in applicable for w in [e.untestable_data(p.ctx)] if w}) if not miss else []
        if weak:
            untestable[eid] = "; ".join(weak)
        elif miss:
            deriv = [m for m in miss if all(is_measured_derivative(a) for a in m.split("|"))]
            untestable[eid] = "needs " + ", ".join(miss) + (
                " (a measured derivative of the output: not a causal input; allow with "
                "allow_measured_derivatives / --allow-measured-derivatives)"
                if deriv and not allow_derivatives else "")
        else:
            testable.append(e)
    return testable, untestable, not_applicable


def diagnose_datasets(train: Mapping[str, Dataset], test: Mapping[str, Dataset] | None = None, *,
                      prior="tilt-drag", config: DiagnoseConfig | None = None, user_effects=None,
                      progress: Callable | None = None, prior_label: str | None = None,
                      decided: Mapping[str, str] | None = None) -> DiagnosisResult:
    """Diagnose ``prior`` on per-target Datasets (see the module docstring).

    ``train``: {target: Dataset} of the training flights (they alone decide); ``test``: the same
    targets on test flights (reported only, never used for a choice); ``prior``: a PriorModel or
    a name; ``decided``: {effect id: which stage of the plan decided it} (not tried here, listed
    as not applicable with that reason). The result's ``final_effects[*]["features"]`` are ready
    to fold into the prior.
    """
    cfg = (config or DiagnoseConfig()).validate()
    if not train:
        raise DataError("no training datasets")
    pr = resolve_prior(prior)
    targets = list(train)
    if test is not None and set(test) != set(targets):
        raise DataError(f"test datasets cover {sorted(test)}, training datasets {sorted(targets)}")
    decided = dict(decided or {})
    effects = _select_effects(user_effects, cfg.effects, decided)
    if cfg.n_blocks is None:
        cfg = replace(cfg, n_blocks=diagnose_blocks(min(len(d) for d in train.values())))
    model = _effect_model(train, test, pr, cfg, targets)
    testable, untestable, not_applicable = _testability(effects, model.tr_parts, targets,
                                                        cfg.allow_measured_derivatives)
    not_applicable.update({k: v for k, v in decided.items() if cfg.effects is None or k in cfg.effects})
    # effects whose signals exist but whose preconditions fail may become testable once another
    # effect refines the inputs (the wind's air speed for quadratic drag): re-checked every step
    pending = [effects[eid] for eid in untestable
               if not any(effects[eid].missing(p.ctx.available()) for p in model.tr_parts
                          if effects[eid].applies_to(p.target))]
    # the family of every candidate the diagnosis may try: each testable effect and each pair of
    # the pair_top best; the k-th step accepted is judged at Holm's alpha / (family − k + 1)
    n_top = min(cfg.pair_top, len(testable) + len(pending)) if cfg.pair_top >= 2 else 0
    family = max(1, len(testable) + len(pending) + n_top * (n_top - 1) // 2)
    search = _Search(model, effects, cfg, family)
    search.assess_own_rows(testable)
    for step in range(cfg.max_steps - len(search.added)):
        for e in list(pending):
            if not any(e.untestable_data(p.ctx) for p in model.tr_parts if e.applies_to(p.target)):
                pending.remove(e)
                testable.append(e)
                untestable.pop(e.id, None)
        if progress:
            progress(step, cfg.max_steps + 1, "scoring effects")
        if not search.step(step + 1, testable) or len(search.added) >= cfg.max_steps:
            break
    search.drop_stand_ins()
    if progress:
        progress(cfg.max_steps, cfg.max_steps + 1, "open-ended search")
    open_ended = search_residuals(model, search.fit, cfg, per_motor="motor_thrust" in search.added,
                                  height="ground_effect" not in untestable)
    final_effects = search.final_effects()
    added, cur = search.added, search.fit
    derivs = sorted({n for fe in final_effects for fs in fe["features"].values() for f in fs
                     for n in uses_derivative(f["expr"])}
                    | {n for eid in added for n in uses_derivative(_needs_signals(effects[eid]))}
                    | {n for o in open_ended.values() if o and o.get("passed")
                       for n in uses_derivative(equation_signals(o))})
    notes = _screening_notes(train, test)
    if derivs:
        notes.append(f"the model uses {', '.join(derivs)}, a measured derivative of the output: "
                     "it cannot be simulated or used by a controller")
    sources = {"train": sorted({s for d in train.values() for s in d.sources}),
               "test": sorted({s for d in test.values() for s in d.sources}) if test else []}
    label = prior_label or (prior if isinstance(prior, str) else getattr(pr, "name", type(pr).__name__))
    return DiagnosisResult(
        targets=_target_summaries(model, search.base_fit, cur, search.terms, search.steps, open_ended),
        steps=search.steps, effects_added=added, untestable=untestable,
        not_detected=[e.id for e in testable if e.id not in added],
        conclusion=_conclusion(added, cfg.max_steps, open_ended, derivs), open_ended=open_ended,
        config=asdict(cfg), prior=label, sources=sources, candidates=search.log,
        final_effects=final_effects, not_applicable=not_applicable, simulable=not derivs, notes=notes,
        series=_series(model, search.base_fit, cur, search.plot_steps))


def _effect_model(train, test, prior, cfg: DiagnoseConfig, targets) -> EffectModel:
    """The stacked model of the prior on the training (and test) datasets, with G at the scale of
    the base refit on the training flights (effects read relative to it)."""
    terms = {t: prior_terms(prior, t) for t in targets}
    tr_parts = [make_part(train[t], t, terms[t], cfg) for t in targets]
    for p in tr_parts:
        if p.y.size < 5 * cfg.n_blocks:
            raise DataError(f"{p.target}: only {p.y.size} training samples; need at least "
                            f"{5 * cfg.n_blocks} for {cfg.n_blocks}-block cross-validation")
    base_beta = EffectModel(tr_parts, None, terms, cfg, targets).fit(
        {n: {p.target: c} for p in tr_parts for n, c in p.base.items()}, {})["beta"]
    terms = {t: terms[t].fitted(t, base_beta) for t in targets}
    tr_parts = [make_part(train[t], t, terms[t], cfg) for t in targets]
    te_parts = [make_part(test[t], t, terms[t], cfg, "test") for t in targets] if test is not None else None
    return EffectModel(tr_parts, te_parts, terms, cfg, targets)


#: the evidence keys a logged candidate keeps
_LOGGED = ("cv_rmse_after", "rel_improvement", "statistic", "p_value", "p_threshold", "blocks_improved",
           "test_rmse_after", "passed", "reasons", "text")


#: the wind's refinement: at most this many rounds, stopped when the air velocity moves by less
#: than the tolerance (m/s) on every row. Each round is a Newton step in ŵ with the drag
#: coefficients held, and they are refit between rounds, so it converges linearly (the step
#: shrinks by about half a round at c = 0.3 1/m: 0.21, 0.098, ... m/s), not quadratically
_REFINE_ROUNDS, _REFINE_TOL_M_S = 20, 1e-3


def _air_columns(model) -> list:
    """The air velocity (``vx_air``, ``vy_air``, m/s) of every part, or None where not set."""
    return [tuple(p.ctx.columns.get(k) for k in ("vx_air", "vy_air"))
            for p in (*model.tr_parts, *(model.te_parts or ()))]


def _moved(before, after) -> float:
    """The largest change (m/s) between two :func:`_air_columns`; inf where one of them is unset
    or a value turns NaN (or back): that is no convergence."""
    worst = 0.0
    for b, a in zip(before, after):
        for x, y in zip(b, a):
            if (x is None) != (y is None) or (x is not None and np.any(np.isnan(x) != np.isnan(y))):
                return math.inf
            if x is not None and x.size and not np.all(np.isnan(x)):
                worst = max(worst, float(np.nanmax(np.abs(x - y))))
    return worst


def _best_first(scores) -> list:
    """Candidates best first by held-out error; one that only fits with impossible values goes
    last (it stands in for something else: the next one is judged instead)."""
    return sorted(scores, key=lambda s: (bool(s[4].get("implausible")), s[4]["cv_rmse_after"]))



class _Search:
    """The forward search's state: the model so far (``terms``, ``test_terms``, ``fit``), the
    steps taken, the effects ``added``, every decision (``log``), the plots' step data and the
    findings of effects judged on their own rows."""

    def __init__(self, model: EffectModel, effects, cfg: DiagnoseConfig, family: int):
        self.model, self.effects, self.cfg, self.family = model, effects, cfg, family
        self.terms, self.test_terms = model.terms_of((), effects)
        self.fit = self.base_fit = model.fit(self.terms, self.test_terms)
        self.steps, self.added, self.log, self.plot_steps, self.findings = [], [], [], [], {}

    def _rmse(self, fit) -> dict:
        return {t: {"train": fit["train"][t], "test": fit["test"][t], "cv": fit["cv"][t]}
                for t in self.model.targets}

    def _plot(self, label: str, et, new) -> dict:
        tidx = self.model.tr.tidx
        return {p.target: {"effect": label, "residual": p.y - self.fit["pred"][tidx == i],
                           "contrib": sum(new["beta"][k] * et[k][p.target] for k in et if p.target in et[k])}
                for i, p in enumerate(self.model.tr_parts)}

    def assess_own_rows(self, testable) -> None:
        """Effects judged on other rows than the v̇ residual (per-motor thrust: the thrust shares),
        once, before the forward steps, by the same rule."""
        cfg, model = self.cfg, self.model
        for e in testable:
            if e.assess_fn is None:
                continue
            p = next(q for q in model.tr_parts if e.applies_to(q.target))
            e0, e1, rows, interp = e.assess(p.ctx, p.block)
            ev = with_test_errors(evidence_of(decide(
                e0, e1, rows, alpha=cfg.alpha, family_size=self.family,
                rank=min(len(self.added) + 1, self.family),
                min_effect_pct=100 * cfg.min_rel_improvement, what=e.id)), None, None)
            ev = held_to_size(ev, interp, cfg.min_rel_improvement)
            entry = {"step": 0, "assessed": e.id, "added": [],
                     "scores": [{"effect": e.id, **{k: ev[k] for k in _LOGGED}}]}
            self.log.append(entry)
            if not ev["passed"] or len(self.added) >= cfg.max_steps:
                continue
            entry["added"] = [e.id]
            self.findings[e.id] = interp
            ev["indistinguishable_from"] = []
            et, ett = model.effect_terms(e)
            new = model.fit({**self.terms, **et}, {**self.test_terms, **ett})
            self.steps.append({"effect": e.id, "description": e.description,
                               "coefficients": strip_effect_id({k: new["beta"][k] for k in et}),
                               "physical": interp.text, "physical_values": interp.values,
                               "physical_per_flight": {}, "per_flight": False, "tested_jointly": None,
                               "rmse": self._rmse(new), "test_note": self.fit.get("test_note"),
                               "evidence": ev})
            self.plot_steps.append(self._plot(e.id, et, new))
            self.terms, self.test_terms, self.fit = {**self.terms, **et}, {**self.test_terms, **ett}, new
            self.added.append(e.id)

    def step(self, number: int, testable) -> bool:
        """One forward step: score every single effect not in yet, pairs when they overlap, and
        add the best if it passes. False when nothing was added (the search stops)."""
        model, cfg = self.model, self.cfg
        rank = min(len(self.added) + 1, self.family)
        singles = []
        for e in testable:
            if e.id in self.added or e.assess_fn is not None:   # assessed once, on their own rows
                continue
            et = model.effect_terms(e)[0]
            if not et or all(np.allclose(c, 0) for cols in et.values() for c in cols.values()):
                continue
            singles.append(e)
        if not singles:
            return False
        scores = _best_first(score_candidates(model, self.fit, self.terms, self.test_terms,
                                              [(e,) for e in singles], self.family, rank))
        entry = {"step": number, "scores": [{"effect": "+".join(e.id for e in g), **{k: ev[k] for k in _LOGGED}}
                                            for g, _, _, _, ev in scores]}
        self.log.append(entry)
        best, jointly = scores[0], False
        if not best[4]["passed"] and best[4]["rel_improvement"] >= cfg.pair_min_gain and cfg.pair_top >= 2:
            pair = self._pairs(scores, rank, entry)
            if pair is not None:
                best, jointly = pair, True
        group, et, ett, new, ev = best
        entry["added"] = [e.id for e in group] if ev["passed"] else []
        if not ev["passed"]:
            log.info("step %d: best candidate %s rejected: %s", number,
                     "+".join(e.id for e in group), "; ".join(ev["reasons"]))
            return False
        # candidates nearly as good (and significant) that the data cannot tell apart
        ev["indistinguishable_from"] = [] if jointly else [
            g[0].id for g, _, _, _, v in scores[1:]
            if v["passed"] and v["rel_improvement"] >= 0.9 * ev["rel_improvement"]]
        self._add(group, et, ett, new, ev, jointly)
        return True

    def _pairs(self, scores, rank: int, entry: dict):
        """Overlapping effects: the pairs of the ``pair_top`` best singles judged jointly (same
        family); a pair must also beat each of its members alone. The best passing pair or None."""
        cfg = self.cfg
        best = scores[0]
        top = [g[0] for g, *_ in scores[:cfg.pair_top]]
        pairs = [(a, b) for i, a in enumerate(top) for b in top[i + 1:]]
        single_cv = {g[0].id: ev["cv_rmse_after"] for g, _, _, _, ev in scores}
        pscores = score_candidates(self.model, self.fit, self.terms, self.test_terms, pairs, self.family, rank)
        for g, _, _, _, ev in pscores:
            worst_single = min(single_cv[e.id] for e in g)
            ev["beats_members"] = ev["cv_rmse_after"] <= (1 - cfg.min_rel_improvement) * worst_single
            if ev["passed"] and not ev["beats_members"]:
                ev["passed"] = False
                ev["reasons"].append("the pair does not beat each of its effects alone by "
                                     f"{100 * cfg.min_rel_improvement:.2f} %")
                ev["text"] = ev["text"].replace(": accepted", ": rejected (" + ev["reasons"][-1] + ")")
        pscores = _best_first(pscores)
        entry["pairs"] = [{"effects": [e.id for e in g], **{k: ev[k] for k in _LOGGED if k != "test_rmse_after"}}
                          for g, _, _, _, ev in pscores]
        entry["pairs_reason"] = (
            f"best single {best[0][0].id} gains {100 * best[4]['rel_improvement']:.1f} % but "
            f"fails ({'; '.join(best[4]['reasons'])}): pairs of the {len(top)} best tested jointly")
        return pscores[0] if pscores and pscores[0][4]["passed"] else None

    def _add(self, group, et, ett, new, ev, jointly: bool) -> None:
        """Take a passing group into the model, one step per effect, then let effects that refine
        the inputs (the wind's air velocity) refresh the contexts and refit until the air velocity
        moves by less than :data:`_REFINE_TOL_M_S` (Newton steps on the wind, the drag refit
        between them; at most :data:`_REFINE_ROUNDS`)."""
        model = self.model
        coef = {k: new["beta"][k] for k in et}
        local = {k: v for k, v in new.get("test_local_beta", {}).items() if k in ett}
        info = model.base_info(new)
        for e in group:
            ce = {k: v for k, v in {**coef, **local}.items() if k.startswith(e.id + ".")}
            self.steps.append({"effect": e.id, "description": e.description,
                               "coefficients": strip_effect_id({k: v for k, v in coef.items()
                                                                if k.startswith(e.id + ".")}),
                               **physical_terms(e, ce, info), "per_flight": e.per_flight,
                               "tested_jointly": [x.id for x in group] if jointly else None,
                               "rmse": self._rmse(new), "test_note": new.get("test_note"),
                               "evidence": ev})
        plot = self._plot("+".join(e.id for e in group), et, new)
        self.plot_steps.extend(plot for _ in group)      # one entry per step (a pair: the joint term)
        self.added.extend(e.id for e in group)
        self.terms, self.test_terms, self.fit = {**self.terms, **et}, {**self.test_terms, **ett}, new
        refiners = [self.effects[eid] for eid in self.added if self.effects[eid].refine_fn is not None]
        for _ in range(_REFINE_ROUNDS if refiners else 0):
            before = _air_columns(model)
            refine_contexts(refiners, model.tr_parts, model.te_parts, self.fit, model.base_info(self.fit),
                            air_jacobians(model, self.effects, self.added, self.fit))
            self.terms, self.test_terms = model.terms_of(self.added, self.effects)
            self.fit = model.fit(self.terms, self.test_terms)
            if _moved(before, _air_columns(model)) < _REFINE_TOL_M_S:
                break

    def drop_stand_ins(self) -> None:
        """Every added effect judged again with all the others in (:func:`drop_stand_ins`)."""
        self.terms, self.test_terms, self.fit = drop_stand_ins(
            self.model, self.effects, self.added, self.findings, self.steps, self.terms,
            self.test_terms, self.fit, self.family)

    def final_effects(self) -> list[dict]:
        """Every added effect in physical terms with the final joint coefficients, and its
        foldable features."""
        model, cur = self.model, self.fit
        info = model.base_info(cur)
        out = []
        for eid in self.added:
            e = self.effects[eid]
            train_coef = {k: v for k, v in cur["beta"].items() if k.startswith(eid + ".")}
            if eid in self.findings:
                physical = {"physical": self.findings[eid].text, "physical_values": self.findings[eid].values,
                            "physical_per_flight": {}}
            else:
                coef = {k: v for k, v in {**cur["beta"], **cur.get("test_local_beta", {})}.items()
                        if k.startswith(eid + ".")}
                physical = physical_terms(e, coef, info)
            out.append({"effect": eid, **physical, "coefficients": strip_effect_id(train_coef),
                        **fold_features(e, model, cur["beta"])})
        return out


def _screening_notes(train, test) -> list[str]:
    """One note per role on the implausible samples screened out of its datasets."""
    notes = []
    for where, sets in (("training", train), ("test", test or {})):
        counts: dict[str, int] = {}
        for d in sets.values():   # each target's dataset counts the signals it uses
            for name, c in d.screened.items():
                counts[name] = max(counts.get(name, 0), c)
        if counts:
            notes.append(f"screened ({where}): " + ", ".join(f"{n} {c}" for n, c in counts.items())
                         + " implausible sample(s) or jump(s) left out before any fit (docs/estimates.md)")
    return notes


def _conclusion(added, max_steps: int, open_ended, derivs) -> str:
    """One sentence: what was added, whether more could be found, the open-ended finding."""
    unnamed = any(o and o.get("passed") for o in open_ended.values())
    # with a significant open-ended term the residual is not exhausted: only the catalogue is
    further = NO_FURTHER.replace("no further effect", "no further catalogue effect") if unnamed else NO_FURTHER
    conclusion = further
    if added:
        conclusion = (f"added {', '.join(added)}; {further}" if len(added) < max_steps
                      else f"added {', '.join(added)} (step limit {max_steps} reached)")
    if unnamed:
        conclusion += "; the open-ended search found an unnamed term (see open_ended)"
    if derivs:
        conclusion += f" (NOT simulable: uses the measured derivative {', '.join(derivs)})"
    return conclusion


def _needs_signals(effect) -> list[str]:
    """The signals an effect's needs name (every alternative)."""
    return [a for grp in effect.needs for a in grp]


def _target_summaries(model, base_fit, cur, cur_terms, steps, open_ended) -> dict:
    out = {}
    for i, p in enumerate(model.tr_parts):
        t, tp = p.target, model.terms[p.target]
        q = model.te_parts[i] if model.te_parts else None
        out[t] = {
            "rmse_prior": {"train": rmse(p.y, p.prior_sum), "test": rmse(q.y, q.prior_sum) if q else None},
            "rmse_before": {k: base_fit[k][t] for k in ("train", "test", "cv")},
            "rmse_after": {k: cur[k][t] for k in ("train", "test", "cv")},
            "base_coefficients": {k.split(":", 1)[1]: v for k, v in base_fit["beta"].items()
                                  if k.startswith(t + ":")},
            "linear_drag_k_D": linear_drag_of(tp, t, p, base_fit["beta"]),
            "linear_drag_k_D_after": linear_drag_of(tp, t, p, cur["beta"]),
            "final_coefficients": {k: v for k, v in cur["beta"].items() if t in cur_terms[k]},
            "steps": [{"effect": s["effect"], "coefficients": s["coefficients"], "physical": s["physical"],
                       "rmse": s["rmse"][t], "evidence": s["evidence"],
                       "tested_jointly": s["tested_jointly"]} for s in steps],
            "open_ended": open_ended.get(t),
            "n_train": int(p.y.size), "n_test": int(q.y.size) if q else 0,
        }
    return out


def _series(model, base_fit, cur, plot_steps) -> dict:
    tidx = model.tr.tidx
    return {p.target: {"t": p.t, "flight": p.flight, "y": p.y,
                       "residual_prior": p.y - p.prior_sum,
                       "residual_before": p.y - base_fit["pred"][tidx == i],
                       "residual_after": p.y - cur["pred"][tidx == i],
                       "signals": {k: v for k, v in p.ctx.columns.items() if k in ("yaw", "speed", "vz_dot", "z", "G", "thrust", "throttle")},
                       "steps": [s[p.target] for s in plot_steps]}
            for i, p in enumerate(model.tr_parts)}

