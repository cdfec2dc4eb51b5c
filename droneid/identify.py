"""The identification pipeline: flights in, identified models compared with the empirical one out.

This is the one place where the stages are composed (habit 1): flights -> ``DatasetBuilder`` ->
train/test :class:`~droneid.data.Dataset` per target; the prior model gives the empirical model
(as 1 feature) and its 3 terms; the constraint set gives constraint samples; R independent SNGP
runs (:mod:`droneid.runner`, local pool or Dask) fit the model; the result is plain data.

- :class:`IdentifyConfig`: every knob, validated once; ``IdentifyConfig.make(quick=...)`` fills the
  paper's budget or the quick one.
- :func:`prepare_target` builds one target's problem (datasets, priors, constraints, empirical
  baselines); :func:`make_jobs` turns it into picklable run jobs; :func:`run_job` runs one SNGP
  fit in a worker; :func:`summarise_target` turns finished runs into a :class:`TargetResult`.
- :func:`identify` composes them for every target and returns an :class:`IdentificationResult`
  (``to_dict()`` is the ``result.json`` document; ``from_dict`` reads it back).
- :func:`select_best` is the model selection, a pure function: the best run is chosen by
  TRAINING error among runs whose model met the constraint threshold, never by test error.

Errors are in the target's units (m/s² for ``v̇``).
"""
from __future__ import annotations

import logging
import math
import re
import platform
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from .data import Dataset
from .errors import ConfigError, DataError, check_choice
from .numerics import lstsq, rmse

__all__ = ["IdentifyConfig", "TargetProblem", "RunJob", "TargetResult", "IdentificationResult",
           "identify", "prepare_target", "make_jobs", "run_job", "summarise_target", "select_best",
           "run_seeds", "PAPER_BUDGET", "QUICK_BUDGET", "TARGETS", "SCHEMA"]

log = logging.getLogger(__name__)

SCHEMA = "droneid.identify/1"
TARGETS = ("vx_dot", "vy_dot", "vz_dot")
#: the paper's setup (Table I), with 10 runs by default instead of 50 (use --runs 50 for the protocol)
PAPER_BUDGET = {"generations": 60000, "population": 500, "runs": 10}
#: a fast look: a few seconds per run on ~200 samples
QUICK_BUDGET = {"generations": 3000, "population": 200, "runs": 4}
METHODS = ("forward", "central", "savgol", "spline")


@dataclass(frozen=True)
class IdentifyConfig:
    """Settings of one identification (all recorded in result.json).

    targets : derivative targets, e.g. ("vx_dot", "vy_dot")
    prior : name of the empirical model (``priors.models.get_prior``), e.g. "tilt-drag"
    prior_features : 0 (no prior), 1 (the empirical model as one feature) or 3 (its three terms)
    constraints : "paper", "none" or the path of a constraints TOML file
    runs : independent SNGP runs per target; jobs : parallel workers (None: all cores);
    scheduler : a Dask scheduler address (``tcp://host:port``) instead of local workers
    generations, population, n_features, max_depth, gamma : SNGP budget (paper: 60000, 500, 10, 7, 0.05)
    n_constraint_samples : samples per constraint for training and (separately) for testing
    seed : root of every random number (run seeds are spawned from ``SeedSequence(seed)``)
    ts, method : dataset sampling period (s) and differentiator
    test_fraction : held-out time block when no test flights are given
    quick : whether the quick budget was asked for (informational; the numbers are above)
    simplify_s : sympy simplification budget per run (s); 0 keeps the raw terms (the study does,
        since it reports errors only: simplification is a third of a paper-budget run)
    prune : "validation" (default: each run searches on 75 % of the training rows and keeps an
        evolved feature only if it lowers the error on the held-out 25 %, then refits on all
        rows; equations stay short and terms fitting noise go) or "exact" (the spec: drop only
        features whose removal changes the training error by < 1e-6; the paper's protocol)
    """
    targets: tuple[str, ...] = ("vx_dot", "vy_dot")
    prior: str = "tilt-drag"
    prior_features: int = 3
    constraints: str = "paper"
    runs: int = PAPER_BUDGET["runs"]
    jobs: int | None = None
    scheduler: str | None = None
    generations: int = PAPER_BUDGET["generations"]
    population: int = PAPER_BUDGET["population"]
    n_features: int = 10
    max_depth: int = 7
    gamma: float = 0.05
    n_constraint_samples: int = 50
    seed: int = 0
    ts: float = 0.05
    method: str = "forward"
    test_fraction: float = 0.3
    quick: bool = False
    simplify_s: float = 2.0
    prune: str = "validation"

    @classmethod
    def make(cls, *, quick: bool = False, **given) -> "IdentifyConfig":
        """A validated config; budget items not given come from the quick or the paper budget."""
        budget = QUICK_BUDGET if quick else PAPER_BUDGET
        unknown = set(given) - {f.name for f in fields(cls)}
        if unknown:
            raise ConfigError(f"unknown identify setting(s): {', '.join(sorted(unknown))}")
        given = {k: v for k, v in given.items() if v is not None or k in ("jobs", "scheduler")}
        for k, v in budget.items():
            given.setdefault(k, v)
        if isinstance(given.get("targets"), str):
            given["targets"] = tuple(s.strip() for s in given["targets"].split(",") if s.strip())
        return cls(quick=quick, **given).validated()

    def validated(self) -> "IdentifyConfig":
        targets = tuple(self.targets)
        if not targets:
            raise ConfigError("The 'targets' parameter must name at least one target. Got none.")
        for t in targets:
            check_choice("target", t, TARGETS)
        if len(set(targets)) != len(targets):
            raise ConfigError(f"The 'targets' parameter names a target twice: {list(targets)}")
        check_choice("prior_features", self.prior_features, (0, 1, 3))
        check_choice("method", self.method, METHODS)
        check_choice("prune", self.prune, ("validation", "exact"))
        if self.constraints not in ("paper", "none") and not Path(self.constraints).is_file():
            raise ConfigError(f"The 'constraints' parameter must be 'paper', 'none' or an existing "
                              f"TOML file. Got {self.constraints!r} instead (no such file).")
        for name, lo in (("runs", 1), ("generations", 1), ("population", 20), ("n_features", 1),
                         ("max_depth", 2), ("n_constraint_samples", 1)):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < lo:
                raise ConfigError(f"The '{name}' parameter must be an integer >= {lo}. Got {v!r} instead.")
        if self.prior_features > self.n_features:
            raise ConfigError(f"prior_features ({self.prior_features}) cannot exceed n_features "
                              f"({self.n_features}): prior features count toward the {self.n_features}")
        if self.jobs is not None and (not isinstance(self.jobs, int) or self.jobs < 1):
            raise ConfigError(f"The 'jobs' parameter must be a positive integer. Got {self.jobs!r} instead.")
        if not (isinstance(self.simplify_s, (int, float)) and 0 <= self.simplify_s < 600):
            raise ConfigError(f"The 'simplify_s' parameter must be in [0, 600) s. Got {self.simplify_s!r} instead.")
        for name in ("ts", "gamma"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"The '{name}' parameter must be a positive number. Got {v!r} instead.")
        if not 0.05 <= self.test_fraction <= 0.8:
            raise ConfigError(f"The 'test_fraction' parameter must be in [0.05, 0.8]. "
                              f"Got {self.test_fraction!r} instead.")
        if not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ConfigError(f"The 'seed' parameter must be a non-negative integer. Got {self.seed!r} instead.")
        return replace(self, targets=targets)

    @property
    def constrained(self) -> bool:
        return self.constraints != "none"

    def to_dict(self) -> dict:
        return asdict(self)

    def engine_params(self) -> dict:
        """Keyword arguments of ``SNGPRegressor`` (without seed/progress)."""
        return {"population_size": int(self.population), "generations": int(self.generations),
                "n_features": int(self.n_features), "max_depth": int(self.max_depth),
                "gamma": float(self.gamma), "simplify_s": float(self.simplify_s),
                "prune": str(self.prune)}


# ------------------------------------------------------------------------------------------------
# one target's problem


@dataclass
class TargetProblem:
    """Everything the runs of one target share (lives in memory only)."""
    target: str
    train: Dataset
    test: Dataset
    test_description: str
    holdout: bool
    priors3: tuple          # PriorFeature x3 (the empirical model's terms)
    prior1: tuple           # PriorFeature x1 (the empirical model as given)
    constraint_set: object | None   # the ConstraintSet the constrained runs train on (or None)
    eval_constraint_set: object | None  # the one e_c is measured against (paper's when 'none')
    cs_test: object | None  # ConstraintSamples for e_c^test, common to every run
    empirical: dict = field(default_factory=dict)
    empirical_refit: dict = field(default_factory=dict)
    series: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)


def run_seeds(seed: int, runs: int) -> tuple[int, list[tuple[int, int]]]:
    """(test-constraint seed, [(engine seed, train-constraint seed) per run]) from SeedSequence(seed).

    Children are spawned in order, so the first R runs of a larger batch are the same runs.
    """
    root = np.random.SeedSequence(int(seed))
    kids = root.spawn(runs + 1)
    test_seed = int(kids[0].generate_state(1)[0])
    return test_seed, [tuple(int(v) for v in k.generate_state(2)) for k in kids[1:]]




def _eval_features(feats, columns: dict, names) -> np.ndarray:
    from .expressions import compile_expression
    cols = [compile_expression(f.expr, names)(columns) for f in feats]
    n = len(next(iter(columns.values())))
    return np.column_stack(cols) if cols else np.empty((n, 0))


def _cs_columns(cs) -> dict:
    return {n: cs.X[:, i] for i, n in enumerate(cs.input_names)}


def _load_constraint_set(spec: str, target: str, prior: str):
    from priors import constraints as pc
    if spec == "none":
        return None
    if spec == "paper":
        return pc.get_constraints("paper", target=target, prior=prior)
    return pc.load_constraints(spec, target=target)


def _constraint_set_for(cfg: IdentifyConfig, target: str):
    """(training constraint set or None, evaluation constraint set or None) for a target.

    Unconstrained runs are still measured against the paper's constraints (as in the paper's
    tables) when the prior defines them for this target.
    """
    train_set = _load_constraint_set(cfg.constraints, target, cfg.prior)
    if train_set is not None:
        return train_set, train_set
    try:
        return None, _load_constraint_set("paper", target, cfg.prior)
    except ConfigError as exc:
        log.info("no paper constraints to measure e_c for %s: %s", target, exc)
        return None, None


def prepare_target(train_flights: Sequence, test_flights: Sequence | None, target: str,
                   cfg: IdentifyConfig) -> TargetProblem:
    """Build the train/test datasets, priors, constraint samples and empirical baselines."""
    from droneid.dataset import DatasetBuilder, split_time_block
    from priors.models import get_prior

    prior = get_prior(cfg.prior)
    inputs = tuple(prior.inputs(target))
    builder = DatasetBuilder(ts=cfg.ts, method=cfg.method)
    ds = builder.build(list(train_flights), target=target, inputs=inputs)
    if test_flights:
        train = ds
        test = builder.build(list(test_flights), target=target, inputs=inputs)
        desc = f"test flights: {', '.join(test.sources) or len(test_flights)}"
        holdout = False
    else:
        train, test = split_time_block(ds, test_fraction=cfg.test_fraction)
        desc = (f"no test flights given: the last {100 * cfg.test_fraction:.0f} % (time block) of "
                f"the training flights is held out as test data")
        holdout = True
    for name, d in (("training", train), ("test", test)):
        if len(d) < 10:
            raise DataError(f"the {name} data for {target} have only {len(d)} samples (need >= 10)")
    priors3 = tuple(prior.features(target))  # every term (the tilt-drag model has 3)
    prior1 = tuple(prior.features(target, 1))
    train_set, eval_set = _constraint_set_for(cfg, target)
    test_seed, _ = run_seeds(cfg.seed, 0)
    cs_test = None
    if eval_set is not None:
        cs_test = eval_set.sample(list(train.input_names), n_per_constraint=cfg.n_constraint_samples,
                                  seed=test_seed)
    p = TargetProblem(target, train, test, desc, holdout, priors3, prior1, train_set, eval_set, cs_test)
    p.notes.extend(range_notes(train, test))
    _empirical_baselines(p)
    return p


def range_notes(train: Dataset, test: Dataset, margin: float = 0.05) -> list[str]:
    """A note when test inputs leave the training range by more than ``margin`` of its span:
    evolved terms (powers, products) extrapolate there and test errors can grow without bound."""
    out = []
    for i, name in enumerate(train.input_names):
        lo, hi = float(np.min(train.X[:, i])), float(np.max(train.X[:, i]))
        tlo, thi = float(np.min(test.X[:, i])), float(np.max(test.X[:, i]))
        pad = margin * max(hi - lo, 1e-12)
        if tlo < lo - pad or thi > hi + pad:
            out.append(f"{name} [{tlo:.3g}, {thi:.3g}] vs training [{lo:.3g}, {hi:.3g}]")
    if not out:
        return []
    return ["the test data leave the training range, where evolved terms extrapolate (test errors "
            "of single runs can grow without bound there): " + "; ".join(out)]


def _empirical_baselines(p: TargetProblem) -> None:
    names = p.train.input_names
    tr_cols, te_cols = p.train.columns(), p.test.columns()
    # as given: the 1-feature prior with its nominal parameters, no fitting at all
    e_tr = _eval_features(p.prior1, tr_cols, names)[:, 0]
    e_te = _eval_features(p.prior1, te_cols, names)[:, 0]
    ec = float("nan")
    e_cs = None
    if p.cs_test is not None:
        from .constraints import constraint_rmse
        e_cs = _eval_features(p.prior1, _cs_columns(p.cs_test), names)[:, 0]
        ec = constraint_rmse(e_cs, p.cs_test)
    p.empirical = {"rmse_train": rmse(e_tr, p.train.y), "rmse_test": rmse(e_te, p.test.y),
                   "constraint_rmse_test": ec, "equation": f"{p.target} = {p.prior1[0].expr}",
                   "expr": str(p.prior1[0].expr)}
    # refit: least squares on the 3 terms + intercept
    A_tr = np.column_stack([_eval_features(p.priors3, tr_cols, names), np.ones(len(p.train))])
    A_te = np.column_stack([_eval_features(p.priors3, te_cols, names), np.ones(len(p.test))])
    beta = lstsq(A_tr, p.train.y)
    r_tr, r_te = A_tr @ beta, A_te @ beta
    ec_refit = float("nan")
    if p.cs_test is not None:
        from .constraints import constraint_rmse
        A_cs = np.column_stack([_eval_features(p.priors3, _cs_columns(p.cs_test), names),
                                np.ones(len(p.cs_test))])
        ec_refit = constraint_rmse(A_cs @ beta, p.cs_test)
    coefs = {f.name: float(b) for f, b in zip(p.priors3, beta[:-1])}
    p.empirical_refit = {"rmse_train": rmse(r_tr, p.train.y), "rmse_test": rmse(r_te, p.test.y),
                         "constraint_rmse_test": ec_refit, "coefficients": coefs,
                         "intercept": float(beta[-1])}
    p.series = {"t": p.test.t, "flight": p.test.flight, "y": p.test.y, "empirical": e_te,
                "empirical_refit": r_te}


# ------------------------------------------------------------------------------------------------
# run jobs (picklable; executed in workers)


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


def make_jobs(p: TargetProblem, cfg: IdentifyConfig, *, prior_features: int | None = None,
              constrained: bool | None = None, variant: str = "") -> list[RunJob]:
    """The R run jobs of one target (prior variant and scenario default to the config's)."""
    nprior = cfg.prior_features if prior_features is None else prior_features
    constrained = cfg.constrained if constrained is None else constrained
    feats = {0: (), 1: p.prior1, 3: p.priors3}[nprior]
    cset = p.constraint_set if p.constraint_set is not None else p.eval_constraint_set
    if constrained and cset is None:
        raise ConfigError(f"constrained runs for {p.target} need constraints, and none are defined "
                          f"for prior '{cfg.prior}' and this target; use --constraints none or FILE")
    _, seeds = run_seeds(cfg.seed, cfg.runs)
    jobs = []
    for i, (engine_seed, cs_seed) in enumerate(seeds):
        cs_train = None
        if constrained:
            cs_train = cset.sample(list(p.train.input_names), n_per_constraint=cfg.n_constraint_samples,
                                   seed=cs_seed)
        jobs.append(RunJob(p.target, variant, i, engine_seed, cfg.engine_params(), p.train.X, p.train.y,
                           p.test.X, p.test.y, tuple(p.train.input_names),
                           tuple(f.expr for f in feats), tuple(f.name for f in feats), cs_train, p.cs_test))
    return jobs


def run_job(job: RunJob) -> dict:
    """Fit one SNGP model and measure it (runs in a worker process)."""
    from droneid.sngp import SNGPRegressor
    t0 = time.perf_counter()
    est = SNGPRegressor(seed=job.seed, **job.engine)
    est.fit(job.X_train, job.y_train, feature_names=list(job.feature_names), priors=list(job.priors),
            prior_names=list(job.prior_names) or None, constraints=job.cs_train)
    pred_test = np.asarray(est.predict(job.X_test), float)
    ec_test = float(est.constraint_rmse(job.cs_test)) if job.cs_test is not None else float("nan")
    ec_train = getattr(est, "constraint_rmse_train_", float("nan"))
    archive = [{"rmse_train": float(a.get("rmse_train", np.nan)),
                "constraint_rmse_train": _float(a.get("constraint_rmse_train"))}
               for a in (getattr(est, "archive_", None) or [])]
    model = est.to_dict()
    return {
        "target": job.target, "variant": job.variant, "index": job.index, "seed": job.seed,
        "rmse_train": float(est.rmse_train_), "rmse_test": rmse(pred_test, job.y_test),
        "constraint_rmse_train": _float(ec_train), "constraint_rmse_test": ec_test,
        "qualified": bool(getattr(est, "qualified_", True)),
        "equation": str(est.equation_), "equation_expanded": _expanded(est),
        "coefficients": {str(k): float(v) for k, v in est.coef_.items()},
        "prior_coefficients": {str(k): float(v) for k, v in (est.prior_coef_ or {}).items()},
        "intercept": float(est.intercept_), "wall_s": float(getattr(est, "wall_s_", time.perf_counter() - t0)),
        "generations": int(getattr(est, "generations_", job.engine.get("generations", 0))),
        "archive": archive, "model": model, "pred_test": pred_test,
        "prior_symbols": {p["symbol"]: p["name"] for p in model.get("priors", []) if "symbol" in p},
    }


def _expanded(est) -> str:
    """The fitted model with the prior features written out, floats to 4 significant figures."""
    from droneid.sngp.model import round_expr, to_text
    expr = getattr(est, "expr_", None)
    if expr is None:
        return str(est.equation_)
    return to_text(round_expr(expr, 4))


def _float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


# ------------------------------------------------------------------------------------------------
# selection and summary (pure)


def select_best(runs: Sequence[dict]) -> int | None:
    """Index of the chosen run: lowest TRAINING error among runs whose model qualified
    (met e_c^train < gamma; every unconstrained run qualifies); if none qualified, the run with
    the lowest training constraint error. Test errors are never looked at. None for no runs."""
    idx = [i for i, r in enumerate(runs) if r is not None]
    if not idx:
        return None
    ok = [i for i in idx if runs[i].get("qualified", True)]
    if ok:
        return min(ok, key=lambda i: (_nan_last(runs[i]["rmse_train"]), i))
    return min(idx, key=lambda i: (_nan_last(runs[i].get("constraint_rmse_train")),
                                   _nan_last(runs[i]["rmse_train"]), i))


def _nan_last(v) -> float:
    v = _float(v)
    return v if math.isfinite(v) else math.inf


def _median(runs, key) -> float:
    vals = np.array([_float(r.get(key)) for r in runs], float)
    vals = vals[np.isfinite(vals)]
    return float(np.median(vals)) if vals.size else float("nan")


def improvement_pct(reference: float, value: float) -> float:
    """How much lower ``value`` is than ``reference``, in percent of the reference."""
    if not (math.isfinite(reference) and math.isfinite(value)) or reference <= 0:
        return float("nan")
    return 100.0 * (reference - value) / reference


RUN_KEYS = ("seed", "rmse_train", "rmse_test", "constraint_rmse_train", "constraint_rmse_test",
            "qualified", "wall_s", "generations", "equation", "equation_expanded", "archive")


@dataclass
class TargetResult:
    """The identification of one target, as plain data (see notes/README_identify.md)."""
    target: str
    inputs: list
    n_train: int
    n_test: int
    test_data: str
    holdout: bool
    prior_features: list            # [{"name", "expr", "description"}] given to the engine
    empirical_terms: list           # the empirical model's 3 terms [{"name", "expr", "description"}]
    equation: str | None            # best model, readable, prior features as ⟨name⟩
    equation_expanded: str | None   # best model, the engine's simplified sympy form
    coefficients: dict
    prior_coefficients: dict
    intercept: float | None
    identified: dict                # best run: rmse_train, rmse_test, constraint_rmse_train/test, seed, qualified
    identified_median: dict         # medians over runs of rmse_train, rmse_test, constraint_rmse_test
    empirical: dict
    empirical_refit: dict
    improvement_pct: dict           # of the best run's rmse_test over empirical / empirical refit
    runs: list
    best_run: int | None
    failed_runs: dict
    model: dict | None              # the best run's SNGPRegressor.to_dict()
    test_series: dict               # t, flight, y, empirical, empirical_refit, identified (test data)
    notes: list = field(default_factory=list)


_LONG_FLOAT = re.compile(r"(?<![\w.])(\d+\.\d{5,}(?:e[+-]?\d+)?)")


def _top_level_sum(text: str) -> bool:
    """Whether ``text`` (sympy's str form) is a sum at the outermost level."""
    depth = 0
    for i, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0 and i > 0 and text[i - 1:i + 2] in (" + ", " - "):
            return True
    return False


def display_term(term: str, prior_symbols: dict | None = None, sig: int = 4) -> tuple[str, bool]:
    """(text, negated): a term with floats to ``sig`` figures and prior symbols as ⟨name⟩; a
    leading minus of a product is moved out (``negated``) and sums are parenthesised."""
    text = _LONG_FLOAT.sub(lambda m: f"{float(m.group(1)):.{sig}g}", str(term))
    for sym in sorted(prior_symbols or {}, key=len, reverse=True):
        text = re.sub(rf"\b{re.escape(sym)}\b", f"⟨{prior_symbols[sym]}⟩", text)
    if _top_level_sum(text):
        return f"({text})", False
    negated = text.startswith("-")
    return text[1:] if negated else text, negated


_LEADING_NUMBER = re.compile(r"^(\d+(?:\.\d*)?(?:e[+-]?\d+)?)\*(?=\S)")


def readable_equation(target: str, coefficients: dict, prior_coefficients: dict, intercept,
                      prior_symbols: dict | None = None, sig: int = 4) -> str:
    """``target = β·⟨prior⟩ + ... + β·term + ... + β0``: prior features by name (also inside
    evolved terms), numbers to ``sig`` significant figures."""
    parts = [(float(b), f"⟨{name}⟩") for name, b in prior_coefficients.items()]
    for term, b in coefficients.items():
        if term in prior_coefficients:
            continue
        text, neg = display_term(term, prior_symbols, sig)
        b = -float(b) if neg else float(b)
        lead = _LEADING_NUMBER.match(text)
        if lead:  # 2.283·8.0*x -> 18.26·x
            b, text = b * float(lead.group(1)), text[lead.end():]
        parts.append((b, text))
    out = [f"{'-' if b < 0 else '+'} {abs(b):.{sig}g}·{term}" for b, term in parts]
    if intercept is not None and _float(intercept) != 0.0:
        out.append(f"{'-' if intercept < 0 else '+'} {abs(intercept):.{sig}g}")
    body = " ".join(out) if out else "0"
    body = body[2:] if body.startswith("+ ") else "-" + body[2:] if body.startswith("- ") else body
    return f"{target} = {body}"


def _feature_dicts(feats) -> list:
    return [{"name": f.name, "expr": str(f.expr), "description": getattr(f, "description", "")}
            for f in feats]


def summarise_target(p: TargetProblem, cfg: IdentifyConfig, runs: Sequence[dict | None],
                     errors: dict | None = None, *, prior_features: int | None = None) -> TargetResult:
    """Turn the finished runs of one target into its result (pure apart from reading ``p``)."""
    nprior = cfg.prior_features if prior_features is None else prior_features
    feats = {0: (), 1: p.prior1, 3: p.priors3}[nprior]
    done = [r for r in runs if r is not None]
    best_i = select_best(done)
    best = done[best_i] if best_i is not None else None
    nan = float("nan")
    metric = ("rmse_train", "rmse_test", "constraint_rmse_test")
    if best is not None:
        identified = {k: best[k] for k in ("rmse_train", "rmse_test", "constraint_rmse_train",
                                           "constraint_rmse_test", "seed", "qualified")}
        median = {k: _median(done, k) for k in metric}
        median["constraint_rmse_train"] = _median(done, "constraint_rmse_train")
        pred = np.asarray(best["pred_test"], float)
    else:
        identified = {k: nan for k in metric}
        median = {k: nan for k in metric}
        pred = np.full(len(p.test), nan)
    notes = [p.test_description, *p.notes]
    if best is not None and not best.get("qualified", True):
        notes.append(f"no run met the constraint threshold e_c^train < {cfg.gamma}: the run with "
                     f"the lowest training constraint error is reported instead")
    if errors:
        notes.append(f"{len(errors)} run(s) failed: " + "; ".join(f"run {i + 1}: {e}" for i, e in errors.items()))
    imp = {"vs_empirical": improvement_pct(p.empirical["rmse_test"], identified["rmse_test"]),
           "vs_empirical_refit": improvement_pct(p.empirical_refit["rmse_test"], identified["rmse_test"]),
           "median_vs_empirical": improvement_pct(p.empirical["rmse_test"], median["rmse_test"])}
    series = {k: np.asarray(v).tolist() for k, v in p.series.items()}
    series["identified"] = pred.tolist()
    series["sources"] = list(p.test.sources)
    return TargetResult(
        target=p.target, inputs=list(p.train.input_names), n_train=len(p.train), n_test=len(p.test),
        test_data=p.test_description, holdout=p.holdout, prior_features=_feature_dicts(feats),
        empirical_terms=_feature_dicts(p.priors3),
        equation=readable_equation(p.target, best["coefficients"], best["prior_coefficients"],
                                   best["intercept"], best.get("prior_symbols")) if best else None,
        equation_expanded=f"{p.target} = {best.get('equation_expanded') or best['equation']}" if best else None,
        coefficients=dict(best["coefficients"]) if best else {},
        prior_coefficients=dict(best["prior_coefficients"]) if best else {},
        intercept=best["intercept"] if best else None,
        identified=identified, identified_median=median,
        empirical=dict(p.empirical), empirical_refit=dict(p.empirical_refit), improvement_pct=imp,
        runs=[{k: r.get(k) for k in RUN_KEYS} for r in done],
        best_run=best_i, failed_runs={str(k): v for k, v in (errors or {}).items()},
        model=best["model"] if best else None, test_series=series, notes=notes)


# ------------------------------------------------------------------------------------------------
# the result document


@dataclass
class IdentificationResult:
    """What ``droneid identify`` produced: per-target results plus config, provenance, versions."""
    targets: dict                   # target -> TargetResult
    config: dict
    provenance: dict
    versions: dict
    interrupted: bool = False
    wall_s: float = 0.0
    backend: str = ""
    notes: list = field(default_factory=list)

    def to_dict(self) -> dict:
        from .io_util import to_jsonable
        return to_jsonable({
            "schema": SCHEMA,
            "targets": {k: asdict(v) if isinstance(v, TargetResult) else v for k, v in self.targets.items()},
            "config": self.config, "provenance": self.provenance, "versions": self.versions,
            "interrupted": self.interrupted, "wall_s": self.wall_s, "backend": self.backend,
            "notes": self.notes})

    @classmethod
    def from_dict(cls, d: dict) -> "IdentificationResult":
        if not isinstance(d, dict) or "targets" not in d:
            raise DataError("not an identification result (no 'targets')")
        names = {f.name for f in fields(TargetResult)}
        targets = {k: TargetResult(**{n: v.get(n) for n in names}) for k, v in d["targets"].items()}
        return cls(targets, d.get("config", {}), d.get("provenance", {}), d.get("versions", {}),
                   bool(d.get("interrupted", False)), float(d.get("wall_s") or 0.0),
                   d.get("backend", ""), list(d.get("notes", [])))


def versions() -> dict:
    import numpy
    import scipy
    import sympy
    from . import __version__
    return {"droneid": __version__, "python": sys.version.split()[0], "numpy": numpy.__version__,
            "scipy": scipy.__version__, "sympy": sympy.__version__, "platform": platform.platform()}


def flight_provenance(flights: Sequence) -> list:
    out = []
    for f in flights:
        prov = getattr(f, "provenance", None)
        if prov is None:
            continue
        d = asdict(prov) if hasattr(prov, "__dataclass_fields__") else dict(prov)
        out.append(d)
    return out


def identify(train_flights: Sequence, test_flights: Sequence | None = None,
             config: IdentifyConfig | None = None, progress: Callable | None = None
             ) -> IdentificationResult:
    """Identify every target of ``config`` from ``train_flights``; see the module docstring.

    Without ``test_flights`` a time block of the training data is held out (the result says so).
    Ctrl-C during the runs returns the finished runs with ``interrupted=True``.
    """
    from .runner import run_jobs
    cfg = (config or IdentifyConfig()).validated()
    if not train_flights:
        raise DataError("no training flights")
    t0 = time.perf_counter()
    problems = {t: prepare_target(train_flights, test_flights, t, cfg) for t in cfg.targets}
    jobs = [j for t in cfg.targets for j in make_jobs(problems[t], cfg)]
    outcome = run_jobs(run_job, jobs, n_jobs=cfg.jobs, scheduler=cfg.scheduler, progress=progress,
                       label="SNGP run")
    targets = {}
    for t in cfg.targets:
        idx = [i for i, j in enumerate(jobs) if j.target == t]
        runs = [outcome.results[i] for i in idx]
        errors = {jobs[i].index: outcome.errors[i] for i in idx if i in outcome.errors}
        if not any(r is not None for r in runs) and not outcome.interrupted:
            first = next(iter(errors.values()), "unknown error")
            raise DataError(f"every SNGP run for {t} failed; the first: {first}")
        targets[t] = summarise_target(problems[t], cfg, runs, errors)
    notes = []
    if outcome.interrupted:
        notes.append(f"interrupted: {outcome.n_done} of {len(jobs)} runs finished and are reported")
    prov = {"train": flight_provenance(train_flights), "test": flight_provenance(test_flights or [])}
    return IdentificationResult(targets, cfg.to_dict(), prov, versions(), outcome.interrupted,
                                time.perf_counter() - t0, outcome.backend, notes)
