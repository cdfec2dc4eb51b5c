"""The paper's multi-run comparison on the user's data (its Tables II-III).

Scenarios baseline (unconstrained) and constrained × prior variants none / 1 / 3 features ×
R runs per target. Every run of every variant is an independent job, so the whole study goes
through one :func:`droneid.engine.runner.run_jobs` batch (local pool or Dask). Per variant the study
reports the median e_d^test and e_c^test over runs, and a Wilcoxon rank-sum p-value
(``scipy.stats.ranksums``) of each prior variant's test errors against the no-prior variant of
the same scenario.

The result is typed data: :func:`study` returns a :class:`StudyResult` (per target a
:class:`StudyTarget`, per scenario × prior variant a :class:`StudyVariant`, per run a
:class:`~droneid.identify.pipeline.RunRecord` summary). ``StudyResult.to_dict()`` is the ``study.json``
document (schema ``droneid.study/1``, docs/result-json.md) and ``StudyResult.from_dict`` reads it
back; :mod:`droneid.report.study` renders either. Errors are RMSEs in the target's units (m/s²
for ``v̇``); NaN where there is no finite value (``null`` in JSON).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from droneid.engine import runner
from droneid.errors import DataError
from droneid.identify.pipeline import (IdentifyConfig, RunRecord, make_jobs, prepare_target, run_job, select_best, versions,
                       flight_provenance)
from droneid.core.io_util import to_jsonable
from droneid.core.numerics import finite_median
from droneid.planning.plan import PAPER_PRIOR, fixed_plan

__all__ = ["study", "StudyResult", "StudyTarget", "StudyVariant", "SCENARIOS", "PRIOR_VARIANTS",
           "STUDY_SCHEMA", "RUN_KEYS", "variant_key", "prior_label"]

SCENARIOS = (("baseline", False), ("constrained", True))
PRIOR_VARIANTS = (0, 1, 3)
STUDY_SCHEMA = "droneid.study/1"
#: what ``study.json`` keeps of each run: its errors, not the archive or the model
RUN_KEYS = ("seed", "rmse_train", "rmse_test", "constraint_rmse_train", "constraint_rmse_test",
            "qualified", "wall_s", "equation")


def variant_key(scenario: str, nprior: int) -> str:
    """The key of a variant in ``StudyTarget.variants`` (and ``study.json``): ``"baseline/1"``."""
    return f"{scenario}/{nprior}"


def prior_label(nprior: int) -> str:
    return "no prior" if nprior == 0 else f"{nprior} prior feature" + ("" if nprior == 1 else "s")


def _ranksum_p(a, b) -> float:
    from scipy.stats import ranksums
    a = np.asarray([v for v in a if v is not None and math.isfinite(v)], float)
    b = np.asarray([v for v in b if v is not None and math.isfinite(v)], float)
    if a.size < 2 or b.size < 2:
        return float("nan")
    return float(ranksums(a, b).pvalue)


def _float(v) -> float:
    """``v`` as a float; ``None`` (JSON's NaN) as NaN."""
    return math.nan if v is None else float(v)


def _run_summary(r: RunRecord) -> RunRecord:
    """The run with only the :data:`RUN_KEYS` fields kept (what ``study.json`` holds of it)."""
    return RunRecord(**{k: getattr(r, k) for k in RUN_KEYS})


# ------------------------------------------------------------------------------------------------
# the result


@dataclass(frozen=True)
class StudyVariant:
    """One scenario × prior variant of one target: its finished runs and their medians.

    ``runs`` are :class:`~droneid.identify.pipeline.RunRecord` summaries holding only the
    :data:`RUN_KEYS` fields (seed, errors in m/s², qualified, wall time in s, equation).
    ``failed`` holds the one-line error of each run that raised. The medians are over the
    finite errors of the runs (m/s²; NaN for none). ``best_equation`` is the equation of the run
    :func:`~droneid.identify.pipeline.select_best` picks by training error (None without runs).
    ``p_value_vs_no_prior`` is the two-sided Wilcoxon rank-sum p-value of the runs' test errors
    against the same scenario's no-prior variant: None for the no-prior variant itself, NaN when
    either side has fewer than two finite test errors.
    """
    scenario: str
    prior_features: int
    runs: tuple[RunRecord, ...] = ()
    failed: tuple[str, ...] = ()
    median_rmse_train: float = math.nan
    median_rmse_test: float = math.nan
    median_constraint_rmse_test: float = math.nan
    best_equation: str | None = None
    p_value_vs_no_prior: float | None = None

    @classmethod
    def from_runs(cls, scenario: str, prior_features: int, runs: Sequence[RunRecord],
                  failed: Sequence[str] = (), p_value_vs_no_prior: float | None = None) -> "StudyVariant":
        """The variant of finished ``runs`` (full records or summaries): medians and the best run's
        equation computed here, the runs kept as summaries."""
        runs = tuple(runs)
        best = select_best(runs)
        return cls(scenario=scenario, prior_features=int(prior_features),
                   runs=tuple(_run_summary(r) for r in runs), failed=tuple(failed),
                   median_rmse_train=finite_median(r.rmse_train for r in runs),
                   median_rmse_test=finite_median(r.rmse_test for r in runs),
                   median_constraint_rmse_test=finite_median(r.constraint_rmse_test for r in runs),
                   best_equation=runs[best].equation if best is not None else None,
                   p_value_vs_no_prior=p_value_vs_no_prior)

    @property
    def key(self) -> str:
        """``variant_key(scenario, prior_features)``, e.g. ``"constrained/3"``."""
        return variant_key(self.scenario, self.prior_features)

    @property
    def n_runs(self) -> int:
        """The number of finished runs."""
        return len(self.runs)

    @property
    def test_errors(self) -> list[float]:
        """e_d^test of every finished run (m/s²; NaN where not finite)."""
        return [r.rmse_test for r in self.runs]

    def to_dict(self) -> dict:
        """The variant as in ``study.json`` (NaN as None)."""
        return to_jsonable({
            "scenario": self.scenario, "prior_features": self.prior_features, "n_runs": self.n_runs,
            "failed": list(self.failed), "median_rmse_train": self.median_rmse_train,
            "median_rmse_test": self.median_rmse_test,
            "median_constraint_rmse_test": self.median_constraint_rmse_test,
            "best_equation": self.best_equation, "runs": [r.summary(RUN_KEYS) for r in self.runs],
            "p_value_vs_no_prior": self.p_value_vs_no_prior})

    @classmethod
    def from_dict(cls, d: Mapping) -> "StudyVariant":
        """The variant back from :meth:`to_dict` (missing medians: NaN; missing runs: none)."""
        if not isinstance(d, Mapping):
            raise DataError(f"a study variant must be an object, got {type(d).__name__}")
        missing = [k for k in ("scenario", "prior_features") if k not in d]
        if missing:
            raise DataError(f"a study variant has no {missing[0]!r}")
        k = int(d["prior_features"])
        p = d.get("p_value_vs_no_prior")
        return cls(scenario=str(d["scenario"]), prior_features=k,
                   runs=tuple(RunRecord.from_dict(_run_fields(r)) for r in d.get("runs") or ()),
                   failed=tuple(str(e) for e in d.get("failed") or ()),
                   median_rmse_train=_float(d.get("median_rmse_train")),
                   median_rmse_test=_float(d.get("median_rmse_test")),
                   median_constraint_rmse_test=_float(d.get("median_constraint_rmse_test")),
                   best_equation=d.get("best_equation"),
                   p_value_vs_no_prior=None if k == 0 and p is None else _float(p))


def _run_fields(r) -> dict:
    if not isinstance(r, Mapping):
        raise DataError(f"a study run must be an object, got {type(r).__name__}")
    return {k: r[k] for k in RUN_KEYS if k in r}


@dataclass(frozen=True)
class StudyTarget:
    """One target of the study: its data, the empirical model's errors and the variants.

    ``n_train`` / ``n_test`` are sample counts; ``test_data`` says where the test data came from.
    ``empirical`` is the empirical model as given ({"rmse_train", "rmse_test",
    "constraint_rmse_test"} in m/s², "equation", "expr"), ``empirical_refit`` its least-squares
    refit ({"rmse_train", "rmse_test", "constraint_rmse_test"} in m/s², "coefficients",
    "intercept"). ``variants`` maps :func:`variant_key` to :class:`StudyVariant`, in
    :data:`SCENARIOS` × :data:`PRIOR_VARIANTS` order.
    """
    n_train: int = 0
    n_test: int = 0
    test_data: str = ""
    notes: tuple[str, ...] = ()
    empirical: dict = field(default_factory=dict)
    empirical_refit: dict = field(default_factory=dict)
    variants: dict = field(default_factory=dict)

    def variant(self, scenario: str, nprior: int) -> StudyVariant:
        """The variant of ``scenario`` with ``nprior`` prior features."""
        key = variant_key(scenario, nprior)
        if key not in self.variants:
            raise DataError(f"the study has no variant {key!r} (it has {', '.join(self.variants) or 'none'})")
        return self.variants[key]

    def to_dict(self) -> dict:
        """The target as in ``study.json`` (NaN as None)."""
        return to_jsonable({
            "n_train": self.n_train, "n_test": self.n_test, "test_data": self.test_data,
            "notes": list(self.notes), "empirical": dict(self.empirical),
            "empirical_refit": dict(self.empirical_refit),
            "variants": {k: v.to_dict() for k, v in self.variants.items()}})

    @classmethod
    def from_dict(cls, d: Mapping) -> "StudyTarget":
        """The target back from :meth:`to_dict` (missing counts: 0; missing texts: empty)."""
        if not isinstance(d, Mapping):
            raise DataError(f"a study target must be an object, got {type(d).__name__}")
        variants = d.get("variants")
        if not isinstance(variants, Mapping):
            raise DataError("a study target has no 'variants' object")
        return cls(n_train=int(d.get("n_train") or 0), n_test=int(d.get("n_test") or 0),
                   test_data=str(d.get("test_data") or ""),
                   notes=tuple(str(n) for n in d.get("notes") or ()),
                   empirical=dict(d.get("empirical") or {}),
                   empirical_refit=dict(d.get("empirical_refit") or {}),
                   variants={str(k): _variant(k, v) for k, v in variants.items()})


def _variant(key, d) -> StudyVariant:
    try:
        return StudyVariant.from_dict(d)
    except (DataError, KeyError, TypeError, ValueError) as exc:
        raise DataError(f"variant {key!r}: {_reason(exc)}") from None


def _reason(exc: Exception) -> str:
    """The first line of an exception's message (its type's name when it has none)."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


@dataclass(frozen=True)
class StudyResult:
    """What :func:`study` produced: per target a :class:`StudyTarget`, plus the config, the data's
    provenance and the versions.

    ``config`` is the study's ``IdentifyConfig.to_dict()`` (after the study's own overrides:
    constraints, no simplification, no effects or delays); ``provenance`` is ``{"train": [...],
    "test": [...]}`` of ``Flight.provenance``; ``interrupted`` says Ctrl-C stopped the batch
    (``runs_finished`` of ``runs_total`` runs finished, the rest are not in ``runs``);
    ``backend`` names where the runs ran (e.g. ``"pool(2)"``); ``wall_s`` is the study's wall
    time in s. ``to_dict()`` is the ``study.json`` document, :meth:`from_dict` reads it back.
    """
    targets: dict = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    versions: dict = field(default_factory=dict)
    interrupted: bool = False
    backend: str = ""
    runs_total: int = 0
    runs_finished: int = 0
    wall_s: float = 0.0

    #: the ``schema`` of the ``study.json`` document
    schema: ClassVar[str] = STUDY_SCHEMA

    def to_dict(self) -> dict:
        """The ``study.json`` document: strict-JSON-ready (numpy converted, NaN as None)."""
        return to_jsonable({
            "schema": self.schema, "targets": {t: tr.to_dict() for t, tr in self.targets.items()},
            "config": self.config, "provenance": self.provenance, "versions": self.versions,
            "interrupted": self.interrupted, "backend": self.backend, "runs_total": self.runs_total,
            "runs_finished": self.runs_finished, "wall_s": self.wall_s})

    @classmethod
    def from_dict(cls, d: Mapping) -> "StudyResult":
        """The result back from :meth:`to_dict` (or the ``study.json`` it was written to).

        Raises :class:`~droneid.errors.DataError` with a one-line reason on a document that is
        not a study result (another schema, no targets, a malformed target or variant)."""
        if not isinstance(d, Mapping):
            raise DataError(f"not a study result: a JSON {type(d).__name__}, expected an object")
        schema = d.get("schema")
        if schema != STUDY_SCHEMA:
            raise DataError(f"not a study result: schema {schema!r}, expected {STUDY_SCHEMA!r}")
        targets = d.get("targets")
        if not isinstance(targets, Mapping):
            raise DataError("not a study result: no 'targets' object")
        parsed = {}
        for t, tr in targets.items():
            try:
                parsed[str(t)] = StudyTarget.from_dict(tr)
            except (DataError, KeyError, TypeError, ValueError) as exc:
                raise DataError(f"not a study result: target {t!r}: {_reason(exc)}") from None
        try:
            return cls(targets=parsed, config=dict(d.get("config") or {}),
                       provenance=dict(d.get("provenance") or {}), versions=dict(d.get("versions") or {}),
                       interrupted=bool(d.get("interrupted", False)), backend=str(d.get("backend") or ""),
                       runs_total=int(d.get("runs_total") or 0), runs_finished=int(d.get("runs_finished") or 0),
                       wall_s=float(d.get("wall_s") or 0.0))
        except (TypeError, ValueError) as exc:
            raise DataError(f"not a study result: {_reason(exc)}") from None


# ------------------------------------------------------------------------------------------------
# the study


def study(train_flights: Sequence, test_flights: Sequence | None, config: IdentifyConfig,
          progress: Callable | None = None) -> StudyResult:
    """Run the study; ``config.runs`` runs per (target, scenario, prior variant).

    Returns a :class:`StudyResult` (``to_dict()`` is the ``study.json`` document). Raises
    :class:`~droneid.errors.DataError` when every run failed (and none was interrupted).
    """
    cfg = config.validated()
    if cfg.constraints == "none":
        cfg = replace(cfg, constraints="paper")
    # the study reports errors only: skip the per-run sympy simplification (a third of a run)
    cfg = replace(cfg, simplify_s=0.0)
    # the paper's protocol: its prior, constraints and data as given (no thrust delay, no folded
    # effects, no drag-sign constraints), whatever identify's defaults are
    cfg = replace(cfg, effects="none", delays="none")
    plan = fixed_plan(cfg)                 # the prior as given (auto: the paper's), resolved once
    cfg = replace(cfg, targets=plan.targets, prior=PAPER_PRIOR if cfg.prior == "auto" else cfg.prior)
    t0 = time.perf_counter()
    problems = {t: prepare_target(train_flights, test_flights, t, cfg, replace(plan, targets=(t,)))
                for t in cfg.targets}
    jobs = []
    for t in cfg.targets:
        for scenario, constrained in SCENARIOS:
            for k in PRIOR_VARIANTS:
                jobs += make_jobs(problems[t], cfg, prior_features=k, constrained=constrained,
                                  variant=variant_key(scenario, k))
    # the paper's protocol: every run spends the whole budget (no early stopping)
    jobs = [replace(j, engine={**j.engine, "early_stop_window": None}) for j in jobs]
    outcome = runner.run_jobs(run_job, jobs, n_jobs=cfg.jobs, scheduler=cfg.scheduler, progress=progress,
                              label="SNGP run")
    targets = {}
    for t in cfg.targets:
        p = problems[t]
        runs, failed = {}, {}
        for scenario, _ in SCENARIOS:
            for k in PRIOR_VARIANTS:
                v = variant_key(scenario, k)
                idx = [i for i, j in enumerate(jobs) if j.target == t and j.variant == v]
                runs[v] = [outcome.results[i] for i in idx if outcome.results[i] is not None]
                failed[v] = [outcome.errors[i] for i in idx if i in outcome.errors]
        variants = {}
        for scenario, _ in SCENARIOS:
            ref = [r.rmse_test for r in runs[variant_key(scenario, 0)]]
            for k in PRIOR_VARIANTS:
                v = variant_key(scenario, k)
                pv = None if k == 0 else _ranksum_p([r.rmse_test for r in runs[v]], ref)
                variants[v] = StudyVariant.from_runs(scenario, k, runs[v], failed[v], pv)
        targets[t] = StudyTarget(n_train=len(p.train), n_test=len(p.test), test_data=p.test_description,
                                 notes=tuple(p.notes), empirical=dict(p.empirical),
                                 empirical_refit=dict(p.empirical_refit), variants=variants)
    if not outcome.n_done and not outcome.interrupted:
        raise DataError("every SNGP run of the study failed; first error: "
                        + next(iter(outcome.errors.values()), "unknown"))
    return StudyResult(targets=targets, config=cfg.to_dict(),
                       provenance={"train": flight_provenance(train_flights),
                                   "test": flight_provenance(test_flights or [])},
                       versions=versions(), interrupted=outcome.interrupted, backend=outcome.backend,
                       runs_total=len(jobs), runs_finished=outcome.n_done,
                       wall_s=time.perf_counter() - t0)
