"""The identification pipeline: flights in, identified models compared with the empirical one out.

The one place where the stages are composed:

    plan (:mod:`droneid.planning.plan`: prior, input offset, effects, from the training flights)
    -> problem (:mod:`droneid.identify.problem`: datasets, prior features, constraints, physical rungs)
    -> search (:mod:`droneid.identify.search`: independent SNGP runs in workers)
    -> ladder (:mod:`droneid.identify.ladder`: guards, the final rung)
    -> result (:mod:`droneid.identify.result`: :class:`TargetResult` per target, :class:`IdentificationResult`)

- :class:`IdentifyConfig`: every knob, validated once; ``IdentifyConfig.make(quick=...)`` fills the
  paper's budget or the quick one. Engine parameters are checked by the engine
  (:meth:`droneid.sngp.SNGPRegressor.default_params` names them).
- :func:`identify` composes the stages for every target; :func:`summarise_target` turns a
  target's finished runs into its :class:`TargetResult`.
- Results are typed (frozen dataclasses in :mod:`droneid.identify.result` and
  :mod:`droneid.identify.ladder`); ``to_dict()`` is the ``result.json`` document (schema
  :data:`SCHEMA`, docs/result-json.md) and ``from_dict`` reads it back, refusing other schemas with
  one line. The result types are importable from here too.

Errors are in the target's units (m/s² for ``v̇``).
"""
from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

import numpy as np

from droneid.engine import runner
from droneid.dataset.builder import reuse_datasets
from droneid.logs.flight import distinct_flights
from droneid.errors import ConfigError, DataError
from droneid.dataset.suitability import check_prior_data
from droneid.fitting.closed_form import SCHEMA, IdentifiedModel
from droneid.fitting.constancy import SHARED_ROLES, across_targets, constancy_sentence, leads
from droneid.fitting.flight_conditions import one_factor_per_flight
from droneid.identify.ladder import TERM_ALPHA, final_rung, per_flight_condition_lead, trivial_errors
from droneid.use.predict import models_from_document, open_loop_section
from droneid.diagnosis.diagnose import plan_identification
from droneid.planning.plan import holdout_cuts, resolve_plan_prior
from droneid.identify.result import FeatureText, IdentificationResult, PlanRecord, TargetResult, flight_provenance, versions
from droneid.identify.problem import TargetProblem, empirical_model, prepare_target
from droneid.core.text import readable_equation, sentences, split_leading_number, undeclared_line
from droneid.fitting.verdict import verdict
from droneid.simulation.rollout import horizon_section
from droneid.rotation.commands import CommandSpeeds
from droneid.simulation.motor_model import MotorModel
from droneid.rotation.stage import RotationJob, RotationResult, rotation_job, score_rotation
from droneid.identify.search import RunRecord, compile_once, make_jobs, run_job, select_best
from droneid.planning.settings import PAPER_BUDGET, QUICK_BUDGET, IdentifyConfig
from droneid.core.targets import targets_for

__all__ = ["IdentifyConfig", "TargetResult", "IdentificationResult", "FeatureText", "identify",
           "prepare_target", "make_jobs", "run_job", "summarise_target", "select_best", "RunRecord",
           "empirical_model", "PAPER_BUDGET", "QUICK_BUDGET", "SCHEMA", "TERM_ALPHA"]

log = logging.getLogger(__name__)



# ------------------------------------------------------------------------------------------------
# the result of one target






def summarise_target(p: TargetProblem, cfg: IdentifyConfig, runs: Sequence[RunRecord | None],
                     errors: dict | None = None, *, prior_features: int | None = None) -> TargetResult:
    """Turn the finished runs of one target into its result (pure apart from reading ``p``)."""
    nprior = cfg.prior_features if prior_features is None else prior_features
    feats = {0: (), 1: p.prior1, 3: p.priors3}[nprior]
    done = [r for r in runs if r is not None]
    best_i = select_best(done)
    best = done[best_i] if best_i is not None else None
    notes = [p.test_description, *p.notes]
    if errors:
        notes.append(f"{len(errors)} run(s) failed: " + "; ".join(f"run {i + 1}: {e}" for i, e in errors.items()))
    final, guards = final_rung(p, cfg, done)
    chosen = done[guards.chosen_run] if guards.chosen_run is not None else None
    identified = {"rmse_train": final.rmse_train, "rmse_test": final.rmse_test,
                  "rmse_validation": final.rmse_validation, "constraint_rmse_test": final.constraint_rmse_test,
                  "constraint_rmse_train": best.constraint_rmse_train if best is not None else math.nan,
                  "seed": chosen.seed if chosen is not None else None,
                  "qualified": best.qualified if best is not None else True}
    if math.isfinite(final.constraint_rmse_test) and final.constraint_rmse_test > cfg.gamma:
        notes.append(f"the final model breaks the prior's formal constraints (e_c = "
                     f"{final.constraint_rmse_test:.3g} m/s² > γ = {cfg.gamma:g}): the data pull its "
                     f"fitted scales away from the physics where there are no data (e.g. zero thrust); "
                     f"trust it inside the training range only")
    if guards.implausible:
        notes.append(f"{guards.implausible} run(s) rejected: their model leaves ±{guards.bound:.3g} "
                     f"{'m/s²' if p.target.startswith('v') else ''} on the training inputs' range ± 20 %")
    series = {k: np.asarray(v).tolist() for k, v in p.series.items()}
    series["identified"] = np.asarray(final.pred_test, float).tolist()
    series["sources"] = list(p.test.sources)
    notes.extend(final.evidence)
    lead = leads(final.constancy, p.plan.diagnosis if p.plan is not None else {},
                 p.plan.offset if p.plan is not None else None,
                 p.plan.thrust_curve if p.plan is not None else None)
    if lead:
        notes.append("; ".join(filter(None, (lead, per_flight_condition_lead(p, final)))))
    ladder = (*p.ladder, final)
    # the target's spread where the errors are measured: the test rows, else the training rows
    spread = float(np.std(p.test.y if len(p.test) else p.train.y))
    vd = verdict(p.target, final, p.ladder[0], guards.chosen_run is not None, p.holdout, spread,
                 reference=p.ladder[1] if len(p.ladder) > 1 else None, gamma=cfg.gamma,
                 trivial=trivial_errors(p.train.y, p.blocks, p.test.y))
    parts = [f"{c:+.4g}·{lab}" for c, lab in (split_leading_number(lab, c) for lab, c in final.terms.items())]
    if final.intercept is not None and final.intercept != 0:
        parts.append(f"{final.intercept:+.4g}")
    cset = p.constraint_set
    return TargetResult(
        target=p.target, inputs=tuple(p.train.input_names), n_train=len(p.train), n_test=len(p.test),
        test_data=p.test_description, holdout=p.holdout,
        constraints=(getattr(cset, "name", "") or "custom") if cset is not None and cfg.constrained else "none",
        prior_features=tuple(map(FeatureText.of_feature, feats)),
        empirical_terms=tuple(map(FeatureText.of_feature, p.priors3)),
        ladder=ladder, guards=guards, verdict=sentences(str(vd), constancy_sentence(final.constancy),
                                                         _offset_caveat(p), _curve_caveat(p)),
        verdict_kind=vd.kind, use=vd.use,
        equation=f"{p.target} = " + " ".join(parts).lstrip("+") if parts else
        readable_equation(p.target, {}, {}, final.intercept),
        identified=identified, empirical=dict(p.empirical), empirical_refit=dict(p.empirical_refit),
        runs=tuple(done), failed_runs={str(k): v for k, v in (errors or {}).items()}, test_series=series,
        notes=tuple(notes), intervals={k.strip("⟨⟩"): v for k, v in final.intervals.items()},
        input_ranges={n: (float(np.min(p.train.X[:, i])), float(np.max(p.train.X[:, i])))
                      for i, n in enumerate(p.train.input_names)} if len(p.train) else {},
        screened={"training": dict(p.train.screened),
                  **({"test": dict(p.test.screened)} if len(p.test) and not p.holdout else {})})


def shared_constants(results: Mapping[str, TargetResult], problems: Mapping[str, TargetProblem]
                     ) -> tuple[dict[str, TargetResult], dict]:
    """The targets' results with the test of one vehicle constant across them
    (:func:`droneid.fitting.constancy.across_targets`: the thrust scale along world x, y and z is one
    constant of the vehicle) in the verdict of each target whose scale takes part when the targets
    disagree, and {role: :class:`~droneid.fitting.constancy.SharedConstant`} tested. Only the prior's own terms of a
    :data:`~droneid.fitting.constancy.SHARED_ROLES` role count, with their final fitted value and
    95 % interval; a held or bounded one is not an estimate."""
    terms: dict[str, dict] = {}
    owner: dict[str, list[str]] = {}
    for t, r in results.items():
        fin = r.final_rung
        for f in problems[t].priors3[:problems[t].n_base]:
            lab = f"⟨{f.name}⟩"
            if f.role not in SHARED_ROLES or lab not in fin.terms or lab not in fin.intervals \
                    or lab in fin.held or lab in fin.at_bound:
                continue
            iv = fin.intervals[lab]
            terms.setdefault(f.role, {})[lab] = (float(fin.terms[lab]), iv.low, iv.high)
            owner.setdefault(t, []).append(lab)
    shared = across_targets(terms)
    payload = _payload_leads(results, problems)
    out = {}
    for t, r in results.items():
        said = [c.sentence(owner.get(t, ())) for c in shared.values()]
        r = replace(r, verdict=sentences(r.verdict, *said)) if any(said) else r
        mine = [s for lab, s in payload.items() if lab in r.final_rung.constancy]
        if mine:
            lead = next((i for i, n in enumerate(r.notes) if n.startswith("leads for the constants that move")), None)
            notes = list(r.notes) + [""] * (lead is None)
            at = len(notes) - 1 if lead is None else lead
            notes[at] = "; ".join(filter(None, (notes[at], *mine)))
            r = replace(r, notes=tuple(notes))
        out[t] = r
    return out, shared


def _payload_leads(results: Mapping[str, TargetResult], problems: Mapping[str, TargetProblem]) -> dict[str, str]:
    """{thrust term label: lead sentence} of :func:`droneid.fitting.flight_conditions.one_factor_per_flight`
    over every target's prior thrust terms tested across the training flights."""
    thrust = {}
    for t, r in results.items():
        for f in problems[t].priors3[:problems[t].n_base]:
            c = r.final_rung.constancy.get(f"⟨{f.name}⟩")
            if f.role == "thrust" and c is not None and c.constant is not None:
                thrust[f"⟨{f.name}⟩"] = c
    return one_factor_per_flight({lab: c for lab, c in thrust.items() if c.constant is False}, thrust)


def _curve_caveat(p: TargetProblem) -> str:
    """The verdict's words on the thrust curve of a command-driven vehicle (its shape, whether
    the data pin it down, the value the log declares), "" for another vehicle."""
    curve = p.plan.thrust_curve if p.plan is not None else None
    return curve.verdict() if curve is not None else ""


def _offset_caveat(p: TargetProblem) -> str:
    """The verdict's words when the targets disagree on the thrust inputs' offset (one clock
    offset of the log cannot be several): the target's thrust and drag scales absorb it."""
    off = p.plan.offset if p.plan is not None else None
    if off is None or off.targets_agree or not p.plan.delays_s:
        return ""
    return ("Its thrust and drag scales are NOT vehicle constants here: the targets disagree on the thrust "
            "inputs' offset (" + ", ".join(f"{t} {1000 * b:+.0f} ms" for t, (b, _, _) in off.per_target.items())
            + "), so the scales absorb what the model lacks.")


# ------------------------------------------------------------------------------------------------
# the result document










def identify(train_flights: Sequence, test_flights: Sequence | None = None,
             config: IdentifyConfig | None = None, progress: Callable | None = None
             ) -> IdentificationResult:
    """Identify every target of ``config`` from ``train_flights``; see the module docstring.

    Without ``test_flights`` a time block of the training data is held out (the result says so).
    Ctrl-C during the runs returns the finished runs with ``interrupted=True``.
    """
    cfg = (config or IdentifyConfig()).validated()
    if not train_flights:
        raise DataError("no training flights")
    train, test, repeated = distinct_flights(train_flights, test_flights or ())
    with reuse_datasets():      # each dataset built once, shared by every stage
        return _identify(train, test or None, cfg, progress, repeated)


def _identify(train_flights: list, test_flights: list | None, cfg: IdentifyConfig,
              progress: Callable | None, repeated: Sequence[str] = ()) -> IdentificationResult:
    t0 = time.perf_counter()
    prior, _ = resolve_plan_prior(cfg, train_flights)
    targets = targets_for(prior, cfg.targets)
    fitness = {"train": check_prior_data(train_flights, prior, targets, cfg.ts, "training")}
    if test_flights:
        fitness["test"] = check_prior_data(test_flights, prior, targets, cfg.ts, "test")
    cuts = None
    if not test_flights and cfg.test_fraction > 0:
        cuts = holdout_cuts(train_flights, cfg, targets[0], prior)
    plan = plan_identification(train_flights, cfg, progress, cuts)
    cfg = replace(cfg, targets=plan.targets)
    aligned = plan.aligned(train_flights)      # each training flight's thrust inputs at its own clock offset
    problems = {t: prepare_target(aligned, test_flights, t, cfg, plan, cuts) for t in cfg.targets}
    jobs = [j for t in cfg.targets for j in make_jobs(problems[t], cfg)]
    notes_early = []
    if cfg.rotation != "none":   # the rotational choice needs no SNGP result: a job beside the runs, first
        try:
            # a command-driven vehicle: the rotors' speeds from their commands through the plan's motor
            # model, each flight's commands at its own clock (the plan's offset is theirs)
            commands = CommandSpeeds.from_record(plan.record())
            jobs.insert(0, rotation_job(train_flights if commands is None else aligned, cfg.frame, commands))
        except DataError as exc:
            notes_early.append(f"rotation not modelled: {exc}")
    compile_once(progress)
    outcome = runner.run_jobs(run_stage_job, jobs, n_jobs=cfg.jobs, scheduler=cfg.scheduler, progress=progress,
                              label="job")
    results = {}
    for t in cfg.targets:
        idx = [i for i, j in enumerate(jobs) if j.target == t]
        runs = [outcome.results[i] for i in idx]
        errors = {jobs[i].index: outcome.errors[i] for i in idx if i in outcome.errors}
        if not any(r is not None for r in runs) and not outcome.interrupted:
            first = next(iter(errors.values()), "unknown error")
            raise DataError(f"every SNGP run for {t} failed; the first: {first}")
        results[t] = summarise_target(problems[t], cfg, runs, errors)
    results, shared = shared_constants(results, problems)
    notes = [*repeated, *plan.lines(), *_data_notes(fitness), *notes_early, *(c.note() for c in shared.values())]
    if outcome.interrupted:     # the SNGP runs (the rotational job is not a run)
        sngp = [i for i, j in enumerate(jobs) if not isinstance(j, RotationJob)]
        notes.append(f"interrupted: {sum(outcome.results[i] is not None for i in sngp)} of {len(sngp)} runs "
                     "finished and are reported")
    prov = {"train": flight_provenance(train_flights), "test": flight_provenance(test_flights or [])}
    record = PlanRecord(
        **plan.record(), validation=next(iter(problems.values())).validation,
        diagnosis=plan.diagnosis, fitness={role: f.to_dict() for role, f in fitness.items() if f is not None})
    rotation_notes: list = []       # why there is no rotational result, if there is none
    rotation = _rotation(outcome, jobs, rotation_notes)
    res = IdentificationResult(results, cfg, record, prov, versions(), outcome.interrupted, 0.0, outcome.backend,
                               (), {}, rotation=rotation,
                               shared_constants=shared)
    horizons = {}
    if test_flights:    # independent scorings of the test flights, side by side on the cores
        stages = ("horizons",) + (("rotation", "open loop") if rotation is not None else ())
        n = cfg.jobs if cfg.jobs is not None else runner.default_jobs()
        done = dict(zip(stages, runner.fork_map(_test_stage, (res, tuple(test_flights)), stages, n)))
        horizons, h_notes = done["horizons"]
        o_notes = []
        if rotation is not None:
            (rotation, _), (open_loop, o_notes) = done["rotation"], done["open loop"]
            rotation = replace(rotation, open_loop_test=open_loop)
        notes += h_notes + rotation_notes + o_notes     # the order of the serial stages they replace
    else:
        notes += rotation_notes
    return replace(res, notes=tuple(notes), horizons=horizons, rotation=rotation, wall_s=time.perf_counter() - t0)


def _test_stage(shared: tuple, stage: str) -> tuple:
    """One scoring of the test flights (``shared``: the result before scoring and the test
    flights; :func:`droneid.engine.runner.fork_map`): (its value, its notes). "horizons": the multi-step
    prediction of the v̇ models (:func:`_horizons`); "rotation": the rotational result with its
    test figures (:func:`_scored_rotation`); "open loop": the benchmark's open-loop table
    (:func:`_open_loop_test`)."""
    res, flights = shared
    notes: list = []
    if stage == "horizons":
        return _horizons(res.targets, flights, notes), notes
    scoring = {"rotation": _scored_rotation, "open loop": _open_loop_test}[stage]
    return scoring(res, flights, notes), notes


def _scored_rotation(res: "IdentificationResult", flights, notes: list) -> RotationResult:
    """``res.rotation`` with its figures on the test flights (open loop with the final v̇ models;
    as it is when a v̇ target is missing)."""
    if not all(t in res.targets for t in ("vx_dot", "vy_dot", "vz_dot")):
        return res.rotation
    models = {t: IdentifiedModel.from_dict(res.targets[t].final.to_dict()) for t in ("vx_dot", "vy_dot", "vz_dot")}
    motor = MotorModel.from_record({"prior_params": res.plan.prior_params, "thrust_curve": res.plan.thrust_curve})
    return score_rotation(res.rotation, flights, models, motor)


def run_stage_job(job):
    """One job of identify's batch (:func:`droneid.engine.runner.run_jobs`): an SNGP run
    (:func:`droneid.identify.search.run_job`) or the rotational choice (:class:`RotationJob`)."""
    return job.run() if isinstance(job, RotationJob) else run_job(job)


def _rotation(outcome, jobs, notes: list) -> RotationResult | None:
    """The rotational job's result (not yet scored on the test flights), or None with a note
    saying why there is none."""
    idx = next((i for i, j in enumerate(jobs) if isinstance(j, RotationJob)), None)
    if idx is None:
        return None
    rot = outcome.results[idx]
    if rot is None or isinstance(rot, str):
        notes.append(f"rotation not modelled: {rot or outcome.errors.get(idx, 'the job did not finish')}")
        return None
    return rot


def _open_loop_test(res: "IdentificationResult", test_flights, notes: list) -> dict:
    """The benchmark's open-loop metric on the test flights, as ``droneid predict --open-loop``
    computes it from result.json (the same digits)."""
    try:
        return open_loop_section(models_from_document(res.to_dict(), where="this result"), test_flights,
                                 horizons=tuple(range(1, 51)))
    except (ConfigError, DataError) as exc:
        notes.append(f"no open-loop figures on the test flights: {exc}")
        return {}


def _data_notes(fitness: Mapping) -> list[str]:
    """The data-fitness warnings of every role ("train", "test"), the flights whose logs do not
    declare their vehicle type said once for all of them (:func:`droneid.dataset.suitability.undeclared_line`)."""
    undeclared = [u for f in fitness.values() if f is not None for u in f.undeclared]
    out = [f"data: {undeclared_line(undeclared)}"] if undeclared else []
    for role, f in fitness.items():
        if f is not None:
            own = undeclared_line(list(f.undeclared)) if f.undeclared else None
            out += [f"data ({role}): {w}" for w in _grouped([w for w in f.warnings if w != own])]
    return out


def _grouped(warnings) -> list[str]:
    """Per-flight warnings ``"name: text"`` with the same text said once, naming every flight."""
    by_text: dict[str, list[str]] = {}
    for w in warnings:
        name, sep, text = w.partition(": ")
        by_text.setdefault(text if sep else w, []).append(name if sep else "")
    return [f"{', '.join(n for n in names if n)}: {text}" if any(names) else text
            for text, names in by_text.items()]


def _horizons(targets: Mapping[str, TargetResult], flights, notes: list, steps=(1, 10, 50)) -> dict:
    """Multi-step prediction of the final, empirical and refit models on the test flights
    (:func:`droneid.simulation.rollout.horizon_section`); {} with a note when it cannot be done."""
    def models(key):   # as result.json holds them, so predict on the saved result gives the same digits
        return {t: IdentifiedModel.from_dict(getattr(tr, key).to_dict()) for t, tr in targets.items()}
    try:
        return horizon_section(models("final"), models("empirical_model"), models("refit_model"),
                               list(flights), horizons=steps)
    except (ConfigError, DataError) as exc:
        notes.append(f"no multi-step prediction on the test flights: {exc}")
        return {}
