"""The search stage of identify: independent SNGP runs of one target as picklable jobs, run in
workers (:mod:`droneid.engine.runner`, a local pool or Dask), and the one selection rule over them.

- :func:`run_seeds` spawns every run's seeds from the config's seed;
- :func:`make_jobs` turns a :class:`droneid.identify.problem.TargetProblem` into :class:`RunJob` s;
- :func:`run_job` fits one SNGP model in a worker and returns a :class:`RunRecord`;
- :func:`select_best` picks by TRAINING error among runs meeting the constraint threshold.

Errors are RMSEs in the target's units (m/s² for v̇).
"""
from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING

import numpy as np

from droneid.errors import ConfigError, DataError
from droneid.core.expressions import round_expr, to_text
from droneid.fitting.terms import defined_samples
from droneid.core.io_util import to_jsonable
from droneid.core.numerics import rmse, to_float
from droneid.sngp import SNGPRegressor
from droneid.sngp.population import min_population
from droneid.sngp.precompile import kernels_ready, warmup
from droneid.sngp.selection import best_index

if TYPE_CHECKING:
    from droneid.identify.problem import TargetProblem

__all__ = ["run_seeds", "RunJob", "make_jobs", "RunRecord", "run_job", "select_best", "compile_once"]

log = logging.getLogger(__name__)


def run_seeds(seed: int, runs: int) -> tuple[int, list[tuple[int, int]]]:
    """(test-constraint seed, [(engine seed, train-constraint seed) per run]) from SeedSequence(seed).

    Children are spawned in order, so the first R runs of a larger batch are the same runs.
    """
    root = np.random.SeedSequence(int(seed))
    kids = root.spawn(runs + 1)
    test_seed = int(kids[0].generate_state(1)[0])
    return test_seed, [tuple(int(v) for v in k.generate_state(2)) for k in kids[1:]]


@dataclass(frozen=True)
class RunJob:
    """One SNGP run: data, priors, constraint samples, budget and seed."""
    target: str
    variant: str
    index: int
    seed: int
    engine: dict
    X_train: np.ndarray
    y_train: np.ndarray
    X_test: np.ndarray
    y_test: np.ndarray
    feature_names: tuple
    priors: tuple
    prior_names: tuple
    cs_train: object | None
    cs_test: object | None


def make_jobs(p: TargetProblem, cfg, *, prior_features: int | None = None,
              constrained: bool | None = None, variant: str = "") -> list[RunJob]:
    """The R run jobs of one target (prior variant and scenario default to the config's;
    ``cfg``: the identify config: runs, seed, budget, constraint samples, search rows)."""
    nprior = cfg.prior_features if prior_features is None else prior_features
    constrained = cfg.constrained if constrained is None else constrained
    feats = {0: (), 1: p.prior1, 3: p.priors3}[nprior]
    need = min_population(len(p.train.input_names), len(feats), cfg.n_features - len(feats))
    if cfg.population_size < need:   # said before any run starts, not by every worker
        raise ConfigError(f"The 'population_size' parameter must be at least {need} for {p.target} "
                          f"({len(p.train.input_names)} inputs, {len(feats)} prior features, {cfg.n_features} "
                          f"features in all). Got {cfg.population_size} instead.")
    cset = p.constraint_set if p.constraint_set is not None else p.eval_constraint_set
    constrained = constrained and cset is not None  # a prior without constraints: said in the notes
    _, seeds = run_seeds(cfg.seed, cfg.runs)
    n = len(p.train)
    step = -(-n // cfg.search_rows) if cfg.search_rows and n > cfg.search_rows else 1
    rows = np.arange(0, n, step)
    jobs = []
    for i, (engine_seed, cs_seed) in enumerate(seeds):
        cs_train = None
        if constrained:
            cs_train, _ = defined_samples(cset.sample(list(p.train.input_names),
                                                      n_per_constraint=cfg.n_constraint_samples, seed=cs_seed),
                                          p.priors3)   # the problem's notes count them
        jobs.append(RunJob(p.target, variant, i, engine_seed, cfg.engine_params(), p.train.X[rows], p.train.y[rows],
                           p.test.X, p.test.y, tuple(p.train.input_names),
                           tuple(f.expr for f in feats), tuple(f.name for f in feats), cs_train, p.cs_test))
    return jobs


@dataclass(frozen=True)
class RunRecord:
    """One finished SNGP run, as :func:`run_job` returns it from a worker.

    Errors are RMSEs in the target's units (m/s² for ``v̇``); constraint errors are NaN when the
    run had no constraint samples. ``equation`` is the engine's form (prior features as symbols),
    ``equation_expanded`` the same model with the prior features written out. ``model`` is the
    estimator's ``to_dict()`` (what ``SymbolicModel.from_dict`` reads); ``pred_test`` the model's
    prediction on the test data (not part of ``result.json``: see :meth:`summary`).
    """
    target: str = ""
    variant: str = ""
    index: int = 0
    seed: int = 0
    rmse_train: float = math.nan
    rmse_test: float = math.nan
    constraint_rmse_train: float = math.nan
    constraint_rmse_test: float = math.nan
    qualified: bool = True
    equation: str = ""
    equation_expanded: str = ""
    coefficients: dict = field(default_factory=dict)
    prior_coefficients: dict = field(default_factory=dict)
    intercept: float = 0.0
    wall_s: float = 0.0
    generations: int = 0
    stopped_early: bool = False
    archive: tuple = ()            # the Pareto archive: ({"rmse_train", "constraint_rmse_train"}, ...)
    model: dict | None = None
    pred_test: np.ndarray | None = field(default=None, repr=False, compare=False)
    prior_symbols: dict = field(default_factory=dict)   # engine symbol -> prior feature name

    #: what ``result.json`` keeps of each run (``runs`` of a target)
    SUMMARY_KEYS = ("seed", "rmse_train", "rmse_test", "constraint_rmse_train", "constraint_rmse_test",
                    "qualified", "wall_s", "generations", "stopped_early", "equation", "equation_expanded",
                    "archive")

    def summary(self, keys: Sequence[str] = SUMMARY_KEYS) -> dict:
        """The fields ``keys`` as a plain dict (the archive as a list)."""
        return {k: list(v) if isinstance(v, tuple) else v for k in keys for v in (getattr(self, k),)}

    def to_dict(self) -> dict:
        """Every field as JSON-ready data (``pred_test`` as a list)."""
        return to_jsonable({f.name: getattr(self, f.name) for f in fields(self)})

    @classmethod
    def from_dict(cls, d: dict) -> "RunRecord":
        """The record back from :meth:`to_dict` or :meth:`summary` (missing fields: defaults;
        null errors: NaN)."""
        if not isinstance(d, dict):
            raise DataError(f"not a run record: {type(d).__name__}")
        names = {f.name for f in fields(cls)}
        kw = {k: v for k, v in d.items() if k in names}
        for k in ("rmse_train", "rmse_test", "constraint_rmse_train", "constraint_rmse_test"):
            if k in kw:
                kw[k] = to_float(kw[k])       # JSON writes NaN as null
        if "archive" in kw:
            kw["archive"] = tuple(kw["archive"] or ())
        if kw.get("pred_test") is not None:
            kw["pred_test"] = np.asarray(kw["pred_test"], float)
        return cls(**kw)


def run_job(job: RunJob) -> RunRecord:
    """Fit one SNGP model and measure it (runs in a worker process)."""
    t0 = time.perf_counter()
    est = SNGPRegressor(seed=job.seed, **job.engine)
    est.fit(job.X_train, job.y_train, feature_names=list(job.feature_names), priors=list(job.priors),
            prior_names=list(job.prior_names) or None, constraints=job.cs_train)
    pred_test = np.asarray(est.predict(job.X_test), float)
    ec_test = float(est.constraint_rmse(job.cs_test)) if job.cs_test is not None else float("nan")
    ec_train = getattr(est, "constraint_rmse_train_", float("nan"))
    archive = tuple({"rmse_train": float(a.get("rmse_train", np.nan)),
                     "constraint_rmse_train": to_float(a.get("constraint_rmse_train"))}
                    for a in (getattr(est, "archive_", None) or []))
    model = est.to_dict()
    return RunRecord(
        target=job.target, variant=job.variant, index=job.index, seed=job.seed,
        rmse_train=float(est.rmse_train_), rmse_test=rmse(pred_test, job.y_test),
        constraint_rmse_train=to_float(ec_train), constraint_rmse_test=ec_test,
        qualified=bool(getattr(est, "qualified_", True)),
        equation=str(est.equation_), equation_expanded=_expanded(est),
        coefficients={str(k): float(v) for k, v in est.coef_.items()},
        prior_coefficients={str(k): float(v) for k, v in (est.prior_coef_ or {}).items()},
        intercept=float(est.intercept_), wall_s=float(getattr(est, "wall_s_", time.perf_counter() - t0)),
        generations=int(getattr(est, "generations_", job.engine.get("generations", 0))),
        stopped_early=bool(getattr(est, "stopped_early_", False)),
        archive=archive, model=model, pred_test=pred_test,
        prior_symbols={p["symbol"]: p["name"] for p in model.get("priors", []) if "symbol" in p})


def _expanded(est) -> str:
    """The fitted model with the prior features written out, floats to 4 significant figures."""
    expr = getattr(est, "expr_", None)
    if expr is None:
        return str(est.equation_)
    return to_text(round_expr(expr, 4))


def select_best(runs: Sequence[RunRecord | None]) -> int | None:
    """Index of the chosen run by the engine's one selection rule (:mod:`droneid.sngp.selection`)
    on TRAINING errors: runs whose model qualified (met e_c^train < gamma; every unconstrained
    run qualifies) by e_d^train, else by e_c^train. Test errors are never looked at. None for no
    runs."""
    return best_index(runs, lambda r: r.rmse_train, lambda r: r.constraint_rmse_train,
                      lambda r: r.qualified)


def compile_once(progress: Callable | None) -> None:
    """Compile the SNGP kernels here, once, when numba's cache lacks them (a fresh clone without
    ``make install``), so the workers load them instead of each compiling at once; says so."""
    if kernels_ready():
        return
    if progress:
        progress(0, 1, "compiling the SNGP kernels (first run only, ~20 s)…")
    s = warmup()
    log.info("SNGP kernels compiled in %.1f s", s)
