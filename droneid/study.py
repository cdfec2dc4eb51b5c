"""The paper's multi-run comparison on the user's data (its Tables II-III).

Scenarios baseline (unconstrained) and constrained × prior variants none / 1 / 3 features ×
R runs per target. Every run of every variant is an independent job, so the whole study goes
through one :func:`droneid.runner.run_jobs` batch (local pool or Dask). Per variant the study
reports the median e_d^test and e_c^test over runs, and a Wilcoxon rank-sum p-value
(``scipy.stats.ranksums``) of each prior variant's test errors against the no-prior variant of
the same scenario. The result is plain data; :mod:`droneid.report.study` renders it.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from . import runner
from .errors import DataError
from .identify import (IdentifyConfig, make_jobs, prepare_target, run_job, select_best, versions,
                       flight_provenance)
from .io_util import to_jsonable
from .numerics import finite_median

__all__ = ["study", "SCENARIOS", "PRIOR_VARIANTS", "variant_key", "prior_label"]

SCENARIOS = (("baseline", False), ("constrained", True))
PRIOR_VARIANTS = (0, 1, 3)
STUDY_SCHEMA = "droneid.study/1"


def variant_key(scenario: str, nprior: int) -> str:
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


def study(train_flights: Sequence, test_flights: Sequence | None, config: IdentifyConfig,
          progress: Callable | None = None) -> dict:
    """Run the study; ``config.runs`` runs per (target, scenario, prior variant)."""
    cfg = config.validated()
    if cfg.constraints == "none":
        cfg = replace(cfg, constraints="paper")
    # the study reports errors only: skip the per-run sympy simplification (a third of a run)
    cfg = replace(cfg, simplify_s=0.0)
    # the paper's protocol: its prior, constraints and data as given (no thrust delay, no folded
    # effects, no drag-sign constraints), whatever identify's defaults are
    cfg = replace(cfg, effects="none", delays="none", prior="tilt-drag" if cfg.prior == "auto" else cfg.prior)
    t0 = time.perf_counter()
    problems = {t: prepare_target(train_flights, test_flights, t, cfg) for t in cfg.targets}
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
    keep = ("seed", "rmse_train", "rmse_test", "constraint_rmse_train", "constraint_rmse_test",
            "qualified", "wall_s", "equation")   # per run in study.json: errors, not the archive
    targets = {}
    for t in cfg.targets:
        p = problems[t]
        variants = {}
        for scenario, _ in SCENARIOS:
            for k in PRIOR_VARIANTS:
                v = variant_key(scenario, k)
                idx = [i for i, j in enumerate(jobs) if j.target == t and j.variant == v]
                runs = [outcome.results[i] for i in idx if outcome.results[i] is not None]
                best = select_best(runs)
                variants[v] = {
                    "scenario": scenario, "prior_features": k, "n_runs": len(runs),
                    "failed": [outcome.errors[i] for i in idx if i in outcome.errors],
                    "median_rmse_train": finite_median(r.rmse_train for r in runs),
                    "median_rmse_test": finite_median(r.rmse_test for r in runs),
                    "median_constraint_rmse_test": finite_median(r.constraint_rmse_test for r in runs),
                    "best_equation": runs[best].equation if best is not None else None,
                    "runs": [r.summary(keep) for r in runs]}
        for scenario, _ in SCENARIOS:
            ref = [r["rmse_test"] for r in variants[variant_key(scenario, 0)]["runs"]]
            for k in PRIOR_VARIANTS:
                v = variants[variant_key(scenario, k)]
                v["p_value_vs_no_prior"] = (None if k == 0 else
                                            _ranksum_p([r["rmse_test"] for r in v["runs"]], ref))
        targets[t] = {"n_train": len(p.train), "n_test": len(p.test), "test_data": p.test_description,
                      "notes": list(p.notes),
                      "empirical": dict(p.empirical),
                      "empirical_refit": {k: v for k, v in p.empirical_refit.items()},
                      "variants": variants}
    if not outcome.n_done and not outcome.interrupted:
        raise DataError("every SNGP run of the study failed; first error: "
                        + next(iter(outcome.errors.values()), "unknown"))
    return to_jsonable({"schema": STUDY_SCHEMA, "targets": targets, "config": cfg.to_dict(),
            "provenance": {"train": flight_provenance(train_flights),
                           "test": flight_provenance(test_flights or [])},
            "versions": versions(), "interrupted": outcome.interrupted, "backend": outcome.backend,
            "runs_total": len(jobs), "runs_finished": outcome.n_done,
            "wall_s": time.perf_counter() - t0})
