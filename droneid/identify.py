"""The identification pipeline: flights in, identified models compared with the empirical one out.

This is the one place where the stages are composed (habit 1): flights -> ``DatasetBuilder`` ->
train/test :class:`~droneid.data.Dataset` per target; the prior model gives the empirical model
(as 1 feature) and its 3 terms; the constraint set gives constraint samples; R independent SNGP
runs (:mod:`droneid.runner`, local pool or Dask) fit the model; the result is plain data.

- :class:`IdentifyConfig`: every knob, validated once; ``IdentifyConfig.make(quick=...)`` fills the
  paper's budget or the quick one.
- :func:`prepare_target` builds one target's problem (datasets, priors, constraints, empirical
  baselines); :func:`make_jobs` turns it into picklable run jobs; :func:`run_job` runs one SNGP
  fit in a worker and returns a :class:`RunRecord`; :func:`summarise_target` turns finished runs into a :class:`TargetResult`.
- :func:`identify` composes them for every target and returns an :class:`IdentificationResult`
  (``to_dict()`` is the ``result.json`` document; ``from_dict`` reads it back).
- :func:`select_best` is the model selection, a pure function: the best run is chosen by
  TRAINING error among runs whose model met the constraint threshold, never by test error.

Errors are in the target's units (m/s² for ``v̇``).
"""
from __future__ import annotations

import inspect
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
import sympy as sp

from priors import constraints as pc
from priors.models import PRIORS, get_prior, is_prior_spec, resolve_prior

from . import __version__, runner
from .constraint_samples import constraint_rmse
from .data import Dataset
from .decide import decide
from .errors import ConfigError, DataError, check_choice
from .expressions import compile_expression, symbol
from .fitness import check_prior_data
from .identified import IdentifiedModel
from .io_util import to_jsonable
from .ladder import (TermModel, drag_slope, drop_negligible, evaluate_expr, physical_fit, plausible,
                     time_blocks, trim_terms, validation_blocks)
from .numerics import finite_median, rmse, to_float
from .rollout import horizon_section
from .sngp import SNGPRegressor
from .sngp.model import SymbolicModel, round_expr, to_text
from .sngp.precompile import kernels_ready, warmup
from .sngp.selection import best_index
from .targets import HORIZONTAL, TARGETS, targets_for, velocity_of
from .plan import (Plan, dataset_builder, fixed_plan, holdout_cuts, plan_identification, prior_terms,
                   resolve_plan_prior, split_terms, train_rows)

__all__ = ["IdentifyConfig", "Verdict", "VERDICT_KINDS", "TargetProblem", "RunJob", "RunRecord", "TargetResult", "IdentificationResult",
           "identify", "prepare_target", "make_jobs", "run_job", "summarise_target", "select_best",
           "run_seeds", "PAPER_BUDGET", "QUICK_BUDGET", "SCHEMA"]

log = logging.getLogger(__name__)

SCHEMA = "droneid.identify/1"
#: the paper's setup per run (Table I); identify makes 4 runs per target by default (the paper: 50;
#: `study` 10): the trust guards decide what survives, and on the shared Crazyflie flights 4 and 10
#: runs give the same final models (measured), in 15 s instead of 43 s
PAPER_BUDGET = {"generations": 60000, "population_size": 500, "runs": 4}
#: family-wise level of keeping evolved terms (Bonferroni over the runs; :mod:`droneid.decide`)
TERM_ALPHA = 0.01
#: a fast look: a few seconds per run on ~200 samples
QUICK_BUDGET = {"generations": 3000, "population_size": 200, "runs": 4}
#: the engine's own defaults (its signature) for what neither budget sets
_ENGINE = SNGPRegressor.default_params()
METHODS = ("forward", "central", "savgol", "spline")


@dataclass(frozen=True)
class IdentifyConfig:
    """Settings of one identification (all recorded in result.json).

    targets : derivative targets, e.g. ("vx_dot", "vy_dot"); None: every target the prior models
    prior : the physical model the search starts from: "auto" (rotor-thrust where the logs have
        motor speeds, motor commands or thrust, tilt-drag otherwise; the choice and its reason are
        in the result), a built-in name (``priors.models.PRIORS``) or ``file.toml:name``
    prior_features : 0 (no prior), 1 (the prior as one feature) or 3 (each of its terms, however
        many: 3 for tilt-drag)
    effects : "auto" (diagnose the refit prior on the training flights and fold every effect that
        passes into the prior features) or "none" (the paper's setting)
    delays : "auto" (choose the input delay of the thrust signals by blocked CV on the training
        flights) or "none"
    empirical, k_D : the user's empirical model every comparison is made against ("tilt-drag" as
        given with this k_D, 1/s); v̇z's empirical model is v̇z = 0 (hover balance)
    margin : an evolved model replaces the physical one only if it lowers the blocked-CV error
        of the training flights by this fraction
    search_rows : SNGP searches on at most this many training rows (every k-th, time order kept;
        0: all); the trust guards refit and validate every proposed term on ALL training rows
    constraints : "paper", "none" or the path of a constraints TOML file
    runs : independent SNGP runs per target; jobs : parallel workers (None: all cores);
    scheduler : a Dask scheduler address (``tcp://host:port``) instead of local workers
    generations, population_size, n_features, max_depth, gamma : SNGP budget (paper: 60000, 500, 10, 7, 0.05)
    n_constraint_samples : samples per constraint for training and (separately) for testing
    seed : root of every random number (run seeds are spawned from ``SeedSequence(seed)``)
    ts, method : dataset sampling period (s) and differentiator
    test_fraction : without test flights: 0 (default) trains on all of the training flights and
        reports validation only; > 0 holds out that last fraction of each flight as test data
        (held out before ANY choice: delay, effects, runs)
    quick : whether the quick budget was asked for (informational; the numbers are above)
    simplify_s : sympy simplification budget per run (s); 0 keeps the raw terms (the study does,
        since it reports errors only: simplification is a third of a paper-budget run)
    prune : "validation" (default: each run searches on 75 % of the training rows and keeps an
        evolved feature only if it lowers the error on the held-out 25 %, then refits on all
        rows; equations stay short and terms fitting noise go) or "exact" (the spec: drop only
        features whose removal changes the training error by < 1e-6; the paper's protocol)
    """
    targets: tuple[str, ...] | None = None
    prior: str = "auto"
    prior_features: int = 3
    constraints: str = "paper"
    runs: int = PAPER_BUDGET["runs"]
    jobs: int | None = None
    scheduler: str | None = None
    generations: int = PAPER_BUDGET["generations"]
    population_size: int = PAPER_BUDGET["population_size"]
    n_features: int = _ENGINE["n_features"]
    max_depth: int = _ENGINE["max_depth"]
    gamma: float = _ENGINE["gamma"]
    n_constraint_samples: int = 50
    seed: int = 0
    ts: float = 0.05
    method: str = "central"
    test_fraction: float = 0.0
    quick: bool = False
    simplify_s: float = 2.0
    prune: str = "validation"
    effects: str = "auto"
    delays: str = "auto"
    empirical: str = "tilt-drag"
    k_D: float = 0.28
    margin: float = 0.05
    search_rows: int = 1000

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
        if self.targets is None:
            self._checked()
            return self
        targets = tuple(self.targets)
        if not targets:
            raise ConfigError("The 'targets' parameter must name at least one target. Got none.")
        self._checked()
        for t in targets:
            check_choice("target", t, TARGETS)
        if len(set(targets)) != len(targets):
            raise ConfigError(f"The 'targets' parameter names a target twice: {list(targets)}")
        return replace(self, targets=targets)

    def _checked(self) -> bool:
        """Validate everything but the targets (raises ConfigError); True."""
        check_choice("prior_features", self.prior_features, (0, 1, 3))
        check_choice("effects", self.effects, ("auto", "none"))
        check_choice("delays", self.delays, ("auto", "none"))
        if not is_prior_spec(self.empirical):
            raise ConfigError(f"The 'empirical' parameter must name a prior (built-in: {', '.join(PRIORS)}; "
                              f"or FILE.toml:NAME). Got {self.empirical!r} instead.")
        if isinstance(self.search_rows, bool) or not isinstance(self.search_rows, (int, np.integer)) \
                or not (self.search_rows == 0 or self.search_rows >= 50):
            raise ConfigError(f"The 'search_rows' parameter must be 0 (all) or an integer >= 50. "
                              f"Got {self.search_rows!r} instead.")
        if not (isinstance(self.margin, (int, float)) and 0 <= self.margin < 0.5):
            raise ConfigError(f"The 'margin' parameter must be in [0, 0.5). Got {self.margin!r} instead.")
        check_choice("method", self.method, METHODS)
        check_choice("prune", self.prune, ("validation", "exact"))
        if self.constraints not in ("paper", "none") and not Path(self.constraints).is_file():
            raise ConfigError(f"The 'constraints' parameter must be 'paper', 'none' or an existing "
                              f"TOML file. Got {self.constraints!r} instead (no such file).")
        for name, lo in (("runs", 1), ("generations", 1), ("population_size", 20), ("n_features", 1),
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
        if not (self.test_fraction == 0 or 0.05 <= self.test_fraction <= 0.8):
            raise ConfigError(f"The 'test_fraction' parameter must be 0 or in [0.05, 0.8]. "
                              f"Got {self.test_fraction!r} instead.")
        if not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ConfigError(f"The 'seed' parameter must be a non-negative integer. Got {self.seed!r} instead.")
        return True

    @property
    def constrained(self) -> bool:
        return self.constraints != "none"

    def to_dict(self) -> dict:
        return asdict(self)

    def engine_params(self) -> dict:
        """Keyword arguments of ``SNGPRegressor``: every estimator parameter this config names,
        under the same name (the run's seed is spawned per run, so not this one)."""
        own = {f.name for f in fields(self)}
        return {k: getattr(self, k) for k in SNGPRegressor.param_names() if k in own and k != "seed"}


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
    plan: object | None = None      # the Plan (prior, delays, effects) the problem was built from
    n_base: int = 0                 # priors3[:n_base] are the prior's terms, the rest effects
    ladder: list = field(default_factory=list)   # rungs before SNGP (see ladder_rungs)
    blocks: np.ndarray | None = None             # CV blocks of the training rows
    validation: str = ""                         # how the blocks were made


def run_seeds(seed: int, runs: int) -> tuple[int, list[tuple[int, int]]]:
    """(test-constraint seed, [(engine seed, train-constraint seed) per run]) from SeedSequence(seed).

    Children are spawned in order, so the first R runs of a larger batch are the same runs.
    """
    root = np.random.SeedSequence(int(seed))
    kids = root.spawn(runs + 1)
    test_seed = int(kids[0].generate_state(1)[0])
    return test_seed, [tuple(int(v) for v in k.generate_state(2)) for k in kids[1:]]




def _eval_features(feats, columns: dict, names) -> np.ndarray:
    cols = [compile_expression(f.expr, names)(columns) for f in feats]
    n = len(next(iter(columns.values())))
    return np.column_stack(cols) if cols else np.empty((n, 0))


def _cs_columns(cs) -> dict:
    return {n: cs.X[:, i] for i, n in enumerate(cs.input_names)}


def _constraint_set_for(cfg: IdentifyConfig, target: str, prior=None, train: Dataset | None = None):
    """(training constraint set or None, evaluation constraint set or None) for a target.

    ``paper`` means the set the prior declares (:meth:`priors.base.PriorModel.constraint_set`):
    the paper's for tilt-drag, one built from the training data for a prior that builds its own
    (rotor-thrust: thrust inputs spanning 0 to their training maximum), the constraints TOML a
    user prior names (:mod:`priors.user`). Inputs no constraint names are held at their training
    median. Unconstrained runs are still measured against that set.
    """
    name = getattr(prior, "name", cfg.prior)

    def own():
        cs, levels, from_data = prior.constraint_set(target, train.columns() if train is not None else None)
        if from_data:                    # built from the training data: always with drag signs
            return _extend(cs, levels)
        return cs if cfg.effects == "none" and cfg.delays == "none" else _extend(cs, {})

    def _extend(cs, level):
        """+ drag-sign constraints up to 1.5 x the training speed along the axis (not in the
        paper's protocol, which ``--effects none --delays none`` keeps)."""
        v = velocity_of(target)
        if train is None or target not in HORIZONTAL or v not in train.input_names:
            return cs
        vmax = 1.5 * float(np.max(np.abs(train.columns()[v])))
        return pc.extended(cs, vmax, level) if vmax > 0 else cs

    def with_medians(cs):
        if cs is None or train is None:
            return cs
        med = {n: float(np.median(train.X[:, i])) for i, n in enumerate(train.input_names)}
        return replace(cs, defaults={**med, **dict(cs.defaults)})
    try:
        paper = with_medians(own())
    except ConfigError as exc:
        log.info("no constraints of prior %s to measure e_c for %s: %s", name, target, exc)
        paper = None
    if cfg.constraints == "none":
        return None, paper
    if cfg.constraints == "paper":
        return paper, paper  # None, None: the prior has no set (a user prior); runs go unconstrained
    cs = with_medians(pc.load_constraints(cfg.constraints, target=target))
    return cs, cs


def prepare_target(train_flights: Sequence, test_flights: Sequence | None, target: str,
                   cfg: IdentifyConfig, plan: Plan | None = None, cuts: dict | None = None) -> TargetProblem:
    """Build the train/test datasets, priors, constraint samples and empirical baselines
    (``cuts``: the hold-out starts of :func:`holdout_cuts`, without test flights)."""
    if plan is None:
        plan = fixed_plan(cfg, (target,))
    if not test_flights and cfg.test_fraction > 0 and cuts is None:
        cuts = holdout_cuts(train_flights, cfg, target, plan.prior)
    prior = plan.prior
    effect_feats = tuple(f for e in plan.effects for f in e["features"].get(target, ()))
    base = split_terms(prior, target)
    extra_inputs = sorted({s for f in effect_feats for s in f.signals} - set(prior.inputs(target)))
    inputs = tuple(prior.inputs(target)) + tuple(extra_inputs)
    empirical_inputs = _empirical_inputs(cfg, target)
    builder = dataset_builder(cfg, plan.delays_s)
    ds = builder.build(list(train_flights), target=target, inputs=inputs,
                       extras=[s for s in empirical_inputs if s not in inputs])
    holdout = not test_flights and cfg.test_fraction > 0
    if test_flights:
        train = ds
        test = builder.build(list(test_flights), target=target, inputs=inputs,
                             extras=[s for s in empirical_inputs if s not in inputs])
        desc = f"test flights: {', '.join(test.sources) or len(test_flights)}"
    elif holdout:
        train, test = train_rows(ds, cuts), train_rows(ds, cuts, test=True)
        desc = (f"no test flights given: the last {100 * cfg.test_fraction:.0f} % (time block) of "
                f"each training flight is held out as test data, before any choice is made")
    else:
        train, test = ds, ds.subset(np.zeros(len(ds), bool))
        desc = ("no test flights given: all training data are used; the errors out of sample are the "
                "validation column (give --test LOG for a transfer check, or --holdout 0.3)")
    for name, d in (("training", train), ("test", test)):
        if len(d) < 10 and (name == "training" or test_flights or holdout):
            raise DataError(f"the {name} data for {target} have only {len(d)} samples (need >= 10)")
    priors3 = base + effect_feats
    prior1 = tuple(prior.features(target, 1))
    train_set, eval_set = _constraint_set_for(cfg, target, prior, train)
    test_seed, _ = run_seeds(cfg.seed, 0)
    cs_test = None
    if eval_set is not None:
        cs_test = eval_set.sample(list(train.input_names), n_per_constraint=cfg.n_constraint_samples,
                                  seed=test_seed)
    p = TargetProblem(target, train, test, desc, holdout, priors3, prior1, train_set, eval_set, cs_test,
                      plan=plan, n_base=len(base))
    if eval_set is None and cfg.constraints != "none":
        p.notes.append(f"prior '{prior.name}' defines no constraints for {target}: the runs are "
                       f"unconstrained and e_c is not measured (give --constraints FILE.toml)")
    if len(test):
        p.notes.extend(range_notes(train, test))
    undelayed = None
    if plan.delays_s:
        b0 = dataset_builder(cfg)
        tr0 = b0.build(list(train_flights), target=target, inputs=inputs,
                       extras=[s for s in empirical_inputs if s not in inputs])
        undelayed = (tr0, b0.build(list(test_flights), target=target, inputs=inputs,
                                   extras=[s for s in empirical_inputs if s not in inputs])) \
            if test_flights else (train_rows(tr0, cuts), train_rows(tr0, cuts, test=True) if holdout
                                  else tr0.subset(np.zeros(len(tr0), bool)))
        # every rung is measured on the same rows: those the delayed inputs exist for
        undelayed = tuple(_same_rows(u, d) for u, d in zip(undelayed, (train, test)))
    _empirical_baselines(p, cfg, undelayed)
    return p


def _fitted_thrust(p: TargetProblem, terms: dict) -> float | None:
    """Median over the training rows of the fitted specific thrust (m/s², the thrust terms'
    fitted scales times their magnitudes, without the direction), or None for priors without
    thrust magnitudes (:meth:`priors.base.PriorModel.fitted_thrust`)."""
    if p.plan is None:
        return None
    lift = p.plan.prior.fitted_thrust(p.target, {k.strip("⟨⟩"): v for k, v in terms.items()},
                                      p.train.columns(), len(p.train))
    return float(np.median(lift)) if lift is not None and len(lift) else None


def _same_rows(ds: Dataset, like: Dataset) -> Dataset:
    """The rows of ``ds`` (same grid, more rows) that ``like`` has: same flight and time."""
    key = lambda d: d.flight.astype(np.int64) * 10**9 + np.round(d.t * 1e4).astype(np.int64)  # noqa: E731
    return ds.subset(np.isin(key(ds), key(like)))


def empirical_prior(cfg: IdentifyConfig):
    """The prior behind the user's empirical model (``cfg.empirical``: a built-in name or
    ``FILE.toml:NAME``), with ``cfg.k_D`` when the prior takes a drag constant."""
    if cfg.empirical in PRIORS and "k_D" in inspect.signature(PRIORS[cfg.empirical]).parameters:
        return get_prior(cfg.empirical, k_D=cfg.k_D)
    return resolve_prior(cfg.empirical)


def _empirical_inputs(cfg: IdentifyConfig, target: str) -> tuple:
    m = empirical_prior(cfg)
    return m.signals(target) if target in m.targets else ()


def empirical_model(cfg: IdentifyConfig, target: str):
    """The user's empirical model as given (an IdentifiedModel): the empirical prior's equation
    as one feature (tilt-drag with ``cfg.k_D`` by default); hover balance, v̇ = 0, for a target
    it does not model (v̇z for tilt-drag)."""
    m = empirical_prior(cfg)
    if target in m.targets:
        k_D = f" (k_D = {m.params['k_D']:g} 1/s)" if "k_D" in m.params else ""
        return IdentifiedModel(target, m.features(target, 1)[0].expr, {},
                               f"the empirical {m.name} model as given{k_D}")
    state = target[:-len("_dot")] if target.endswith("_dot") else target
    return IdentifiedModel(target, sp.Integer(0), {}, f"hover balance as given: {state[0]}\u0307{state[1:]} = 0")


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


def _ec(pred_cs, cs) -> float:
    return float(constraint_rmse(pred_cs, cs)) if cs is not None else float("nan")


def rung(name: str, description: str, model, train: Dataset, test: Dataset, cs, *,
         blocks=None, fitted: bool = True, terms: dict | None = None, delays=None) -> dict:
    """One rung of the ladder: a model (IdentifiedModel, or a TermModel: fitted here, robust and
    bounded, with 95 % block-bootstrap intervals and unidentifiable physical coefficients held at
    their nominal value, :func:`droneid.ladder.physical_fit`) measured on the training rows
    (train; validation = blocked CV of the same terms refit without each block, or the training
    error for a model with nothing fitted), the test rows and the constraints."""
    tr_cols, te_cols = train.columns(), test.columns()
    evidence = None
    if isinstance(model, TermModel):
        evidence = physical_fit(model, tr_cols, train.y, bootstrap_blocks(train))
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
    return {"name": name, "description": description, "rmse_train": rmse(p_tr, train.y),
            "rmse_validation": val, "rmse_test": rmse(p_te, test.y),
            "constraint_rmse_test": _ec(p_cs, cs) if p_cs is not None else float("nan"),
            "terms": dict(terms or {}), "intercept": intercept, "model": final.to_dict(),
            "intervals": {k: list(v) for k, v in evidence.intervals.items()} if evidence else {},
            "held": dict(evidence.held) if evidence else {},
            "at_bound": dict(evidence.at_bound) if evidence else {},
            "evidence": list(evidence.notes) if evidence else [],
            "pred_test": p_te}


def bootstrap_blocks(ds: Dataset, **need) -> np.ndarray:
    """The time blocks the intervals resample and the block tests use
    (:func:`droneid.ladder.time_blocks`: ~150 samples each; ``need``: family and alpha of a test)."""
    return time_blocks(ds.t, ds.flight, **need)


def _physical_model(p: TargetProblem, features) -> TermModel:
    """The unfitted physical model of ``p`` over ``features`` (prior terms and effects): bounds,
    gravity and intercept bounds as the prior declares them."""
    if p.plan is None:
        return TermModel.of(features)
    return prior_terms(p.plan.prior, p.target, features)


def _empirical_baselines(p: TargetProblem, cfg: IdentifyConfig | None = None,
                         undelayed: tuple | None = None) -> None:
    """The ladder's physical rungs: the empirical model as given, the prior refit (without the
    input delay: on ``undelayed`` = (train, test) when a delay was chosen), + the delay, + each
    folded effect. Fills p.empirical, p.empirical_refit, p.series and p.ladder."""
    cfg = cfg or IdentifyConfig()
    plan = p.plan
    p.blocks, p.validation = validation_blocks(p.train.t, p.train.flight)
    emp = empirical_model(cfg, p.target)
    cs = p.cs_test
    ladder = [rung("empirical", emp.description, emp, p.train, p.test, cs, fitted=False)]
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
        ladder.append(rung("delay", what,
                           tm, p.train, p.test, cs, blocks=p.blocks, delays=plan.delays_s))
    else:
        ladder.append(rung("refit", f"{prior_name} prior refit",
                           tm, p.train, p.test, cs, blocks=p.blocks, delays=plan.delays_s if plan else None))
    for e in (plan.effects if plan else ()):
        feats = e["features"].get(p.target, ())
        if not feats:
            continue
        base = base + tuple(feats)
        tm = _physical_model(p, base)
        ladder.append(rung(f"effect:{e['effect']}", f"+ {e['effect']} ({e['physical']})",
                           tm, p.train, p.test, cs, blocks=p.blocks, delays=plan.delays_s))
    p.ladder = ladder
    lift = _fitted_thrust(p, ladder[-1]["terms"])
    if lift is not None and not lift > 0:
        p.notes.append(f"the fitted thrust is not positive over the training data (median {lift:.3g} m/s²): "
                       f"these data cannot separate thrust from gravity and drag (e.g. a flight at constant "
                       f"height); this {p.target} model is not physical")
    e0, r1 = ladder[0], ladder[1]
    p.empirical = {"rmse_train": e0["rmse_train"], "rmse_test": e0["rmse_test"],
                   "constraint_rmse_test": e0["constraint_rmse_test"],
                   "equation": e0["model"]["equation"], "expr": e0["model"]["expr"]}
    p.empirical_refit = {"rmse_train": r1["rmse_train"], "rmse_test": r1["rmse_test"],
                         "constraint_rmse_test": r1["constraint_rmse_test"],
                         "coefficients": {k.strip("⟨⟩"): v for k, v in r1["terms"].items()},
                         "intercept": r1["intercept"]}
    p.series = {"t": p.test.t, "flight": p.test.flight, "y": p.test.y, "empirical": e0["pred_test"],
                "empirical_refit": r1["pred_test"] if len(r1["pred_test"]) == len(p.test) else
                ladder[-1]["pred_test"]}


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
    constrained = constrained and cset is not None  # a prior without constraints: said in the notes
    _, seeds = run_seeds(cfg.seed, cfg.runs)
    n = len(p.train)
    step = -(-n // cfg.search_rows) if cfg.search_rows and n > cfg.search_rows else 1
    rows = np.arange(0, n, step)
    jobs = []
    for i, (engine_seed, cs_seed) in enumerate(seeds):
        cs_train = None
        if constrained:
            cs_train = cset.sample(list(p.train.input_names), n_per_constraint=cfg.n_constraint_samples,
                                   seed=cs_seed)
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


# ------------------------------------------------------------------------------------------------
# selection and summary (pure)


def select_best(runs: Sequence[RunRecord | None]) -> int | None:
    """Index of the chosen run by the engine's one selection rule (:mod:`droneid.sngp.selection`)
    on TRAINING errors: runs whose model qualified (met e_c^train < gamma; every unconstrained
    run qualifies) by e_d^train, else by e_c^train. Test errors are never looked at. None for no
    runs."""
    return best_index(runs, lambda r: r.rmse_train, lambda r: r.constraint_rmse_train,
                      lambda r: r.qualified)


def improvement_pct(reference: float, value: float) -> float:
    """How much lower ``value`` is than ``reference``, in percent of the reference."""
    if not (math.isfinite(reference) and math.isfinite(value)) or reference <= 0:
        return float("nan")
    return 100.0 * (reference - value) / reference


@dataclass
class TargetResult:
    """The identification of one target, as plain data (the ``result.json`` schema:
    docs/result-json.md)."""
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
    ladder: list = field(default_factory=list)   # rungs: empirical -> refit -> delay -> effects -> final
    final: dict | None = None       # the final model (IdentifiedModel.to_dict()): what predict applies
    empirical_model: dict | None = None  # the user's empirical model as given (IdentifiedModel.to_dict())
    refit_model: dict | None = None      # the prior's least-squares refit (IdentifiedModel.to_dict())
    verdict: str = ""               # one sentence, first thing a user reads
    guards: dict = field(default_factory=dict)   # runs rejected as implausible, terms dropped, bound
    intervals: dict = field(default_factory=dict)  # {coefficient: [low, high]}: the final model's 95 % intervals
    verdict_kind: str = ""          # better / no better / worse / not to be trusted / no verdict
    screened: dict = field(default_factory=dict)  # {"training"|"test": {signal: implausible samples}}
    input_ranges: dict = field(default_factory=dict)  # {input: [min, max]} over the training rows


_LONG_FLOAT = re.compile(r"(?<![\w.])(\d+\.\d{5,}(?:e[+-]?\d+)?)")


def round_floats(text: str, sig: int = 4) -> str:
    """``text`` with every float of 5 or more decimals written to ``sig`` significant figures."""
    return _LONG_FLOAT.sub(lambda m: f"{float(m.group(1)):.{sig}g}", str(text))


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
    text = round_floats(term, sig)
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
    if intercept is not None and to_float(intercept) != 0.0:
        out.append(f"{'-' if intercept < 0 else '+'} {abs(intercept):.{sig}g}")
    body = " ".join(out) if out else "0"
    body = body[2:] if body.startswith("+ ") else "-" + body[2:] if body.startswith("- ") else body
    return f"{target} = {body}"


def _feature_dicts(feats) -> list:
    return [{"name": f.name, "expr": str(f.expr), "description": getattr(f, "description", "")}
            for f in feats]


def _final_rung(p: TargetProblem, cfg: IdentifyConfig, done: Sequence[RunRecord]) -> tuple[dict, dict]:
    """(final rung, guard report): the best evolved model that survives the trust guards, or the
    physical rung (prior + delay + effects) when none beats it on TRAINING validation blocks by
    the calibrated block test of :mod:`droneid.decide` (held-out errors of both, time blocks,
    α = :data:`TERM_ALPHA` Bonferroni over the runs, at least ``cfg.margin`` lower error).

    Guards, in order, per run: the run's evolved terms are added to ALL prior and effect
    features; near-duplicate columns (cancelling pairs) are merged and evolved terms that do not
    lower the blocked-CV error by 1 % are dropped (:func:`droneid.ladder.trim_terms`); the
    model must stay within ±(2·max|y_train| + g) on a grid spanning the training inputs ± 20 %
    (:func:`droneid.ladder.plausible`); its constraint error on a training draw of the constraint
    samples must stay below max(γ, 1.1 x the physical rung's); drag must grow with speed: along
    its own-axis velocity (±1.2 x the training speed, other inputs at 50 flown states) the
    model's slope may not exceed the physical rung's (or 0) by more than 0.05 1/s. The survivor with the lowest CV error replaces the
    physical rung only if it passes that test."""
    phys = p.ladder[-1]
    delays = p.plan.delays_s if p.plan else {}
    cols, y = p.train.columns(), p.train.y
    phys_model = _physical_model(p, p.priors3)
    phys_tm = phys_model.fit(cols, y)      # the physical rung refit on the training rows, once
    base = phys_model.terms
    bound = 2.0 * float(np.max(np.abs(y))) + 9.81
    ranges = {n: (float(np.min(p.train.X[:, i])), float(np.max(p.train.X[:, i])))
              for i, n in enumerate(p.train.input_names)}
    guards = {"bound": bound, "implausible": 0, "no_evolved_term_left": 0, "constraints_broken": 0,
              "dropped": [], "candidates": 0}
    cset = p.constraint_set if p.constraint_set is not None else p.eval_constraint_set
    cs_sel, ec_limit = None, math.inf
    if cset is not None:  # a training draw of constraint samples (not the e_c^test draw)
        cs_sel = cset.sample(list(p.train.input_names), n_per_constraint=cfg.n_constraint_samples,
                             seed=run_seeds(cfg.seed + 1, 0)[0])
        ec_phys = _ec(phys_tm.predict(_cs_columns(cs_sel), len(cs_sel)), cs_sel)
        ec_limit = max(cfg.gamma, 1.1 * ec_phys)
        guards["constraint_limit"] = ec_limit
    vel = velocity_of(p.target)
    slope_limit, rows, v_max = math.inf, {}, 0.0
    if vel in p.train.input_names:
        pick = np.random.default_rng(cfg.seed).choice(len(p.train), size=min(50, len(p.train)), replace=False)
        rows = {n: p.train.X[pick, j] for j, n in enumerate(p.train.input_names)}
        v_max = 1.2 * float(np.max(np.abs(cols[vel])))
        phys_slope = drag_slope(phys_tm.expr(), vel, rows, v_max)
        slope_limit = max(phys_slope, 0.0) + 0.05
        guards["drag_slope_limit"] = slope_limit
    guards["drag_not_monotone"] = 0
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
        evolved = [t.xreplace(subs) for t in raw]
        if not evolved:
            guards["no_evolved_term_left"] += 1
            continue
        shown = [display_term(to_text(round_expr(t, 4)), {k: m.prior_labels.get(k, k) for k in m.priors})
                 for t in raw]
        tm = phys_model.extended(evolved, tuple(("-" if neg else "") + txt for txt, neg in shown))
        sizes = [0] * len(base) + [int(sp.count_ops(t)) for t in raw]
        trimmed, notes = trim_terms(tm, cols, y, p.blocks, keep_first=len(base), sizes=sizes)
        guards["dropped"].extend(f"run {i + 1}: {n}" for n in notes)
        if len(trimmed.terms) == len(base):
            guards["no_evolved_term_left"] += 1
            continue
        pl = plausible(trimmed.expr(), ranges, bound)
        if not pl.ok:
            guards["implausible"] += 1
            guards["dropped"].append(f"run {i + 1}: rejected, {pl.note}")
            continue
        if cs_sel is not None:
            ec = _ec(trimmed.predict(_cs_columns(cs_sel), len(cs_sel)), cs_sel)
            if not ec <= ec_limit:
                guards["constraints_broken"] += 1
                guards["dropped"].append(f"run {i + 1}: rejected, constraint error {ec:.3g} > {ec_limit:.3g}")
                continue
        if rows:
            slope = drag_slope(trimmed.expr(), vel, rows, v_max)
            if not slope <= slope_limit:
                guards["drag_not_monotone"] += 1
                guards["dropped"].append(f"run {i + 1}: rejected, ∂{p.target}/∂{vel} reaches {slope:.3g} 1/s "
                                         f"within ±{v_max:.3g} m/s (drag must grow with speed)")
                continue
        cv = trimmed.cv_rmse(cols, y, p.blocks)
        guards["candidates"] += 1
        if best is None or cv < best[0]:
            best = (cv, i, trimmed)
    decision = None
    if best is not None:   # the calibrated rule of droneid.decide: held-out errors, time blocks, Bonferroni over the runs
        err0 = y - phys_model.cv_predictions(cols, y, p.blocks)
        err1 = y - best[2].cv_predictions(cols, y, p.blocks)
        decision = decide(err0, err1, bootstrap_blocks(p.train, family=max(len(done), 1), alpha=TERM_ALPHA),
                          alpha=TERM_ALPHA, family_size=max(len(done), 1),
                          min_effect_pct=100 * cfg.margin, what=f"evolved terms of run {best[1] + 1}")
        guards["decision"] = decision.evidence
    if decision is not None and decision.accepted:
        cv, i, tm = best
        n_ev = len(tm.terms) - len(base)
        final = rung("final", f"+ {n_ev} evolved term{'s' * (n_ev > 1)} (run {i + 1})", tm, p.train, p.test,
                     p.cs_test, blocks=p.blocks, delays=delays)
        guards["chosen_run"] = i
    else:
        final = dict(phys, name="final", description=f"= the rung above (no evolved term passed the block "
                     f"test: {100 * cfg.margin:.0f} % lower held-out error at α = {TERM_ALPHA:g})")
        guards["chosen_run"] = None
        if best is not None:
            guards["best_evolved_validation"] = best[0]
    return final, guards


#: what a verdict says, and the colour the report gives it
VERDICT_KINDS = {"better": "green", "no better": "grey", "worse": "red", "not to be trusted": "amber",
                 "no verdict": "grey"}


@dataclass(frozen=True)
class Verdict:
    """One sentence a user reads first, and its kind (a key of :data:`VERDICT_KINDS`)."""
    kind: str
    text: str

    def __str__(self) -> str:
        return self.text


def _physics_problems(final: dict, reference: dict | None, gamma: float) -> list[str]:
    """What makes a model untrustworthy as physics: coefficients the data pull outside their
    physical bounds, and a constraint error above γ that the prior's own refit does not explain."""
    out = [f"{k.strip('⟨⟩')} is pulled outside its physical range (held at {v:.3g})"
           for k, v in (final.get("at_bound") or {}).items()]
    ec = to_float(final.get("constraint_rmse_test"))
    ref = to_float((reference or {}).get("constraint_rmse_test"))
    if math.isfinite(ec) and ec > gamma and not (math.isfinite(ref) and ec <= 1.1 * ref):
        out.append(f"it breaks the prior's constraints (e_c = {ec:.3g} > γ = {gamma:g})")
    return out


def verdict(target: str, final: dict, empirical: dict, evolved: bool, holdout: bool,
            y_spread: float = math.inf, *, reference: dict | None = None, gamma: float = math.inf) -> Verdict:
    """How the final model compares with the empirical model as given, on the test data (or,
    without any, on the training flights' validation blocks), with the absolute errors and the
    target's standard deviation. "better" needs all of: better in validation, every physical
    coefficient inside its bounds, e_c within γ (or no worse than the prior's own refit,
    ``reference``); otherwise the verdict says what is wrong and that the model is not to be
    trusted. A target that barely varies, or an error that cannot be measured, gives no verdict
    (never a "+100 %")."""
    te, ee = final["rmse_test"], empirical["rmse_test"]
    va, ev = final["rmse_validation"], empirical["rmse_validation"]
    has_test = math.isfinite(te) and math.isfinite(ee)
    where = ("on the held-out block" if holdout else "on the test flights") if has_test else \
        "on validation blocks of the training flights (no test data)"
    if not y_spread > 1e-3:
        return Verdict("no verdict", f"{target}: no verdict: the measured {target} barely varies (spread "
                       f"{y_spread:.2g}); these data cannot tell models apart")
    a, b = (te, ee) if has_test else (va, ev)
    if not (math.isfinite(a) and math.isfinite(b)) or b <= 0:
        return Verdict("no verdict", f"{target}: no verdict: the errors could not be measured")
    gain, vgain = improvement_pct(b, a), improvement_pct(ev, va)
    what = "identified model (with evolved terms)" if evolved else \
        "physical model (prior + effects; no evolved term survived validation)"
    sd = f"σ({target}) {y_spread:.3g}" if math.isfinite(y_spread) else ""
    errs = f"RMSE {a:.3g} vs {b:.3g} m/s²" + (f", {sd}" if sd else "")
    extra = f"; validation {vgain:+.0f} %" if has_test else ""
    problems = _physics_problems(final, reference, gamma)
    if problems:
        return Verdict("not to be trusted",
                       f"{target}: the {what} is NOT TO BE TRUSTED: " + "; ".join(problems)
                       + f" ({gain:+.0f} % vs the empirical model {where}: {errs}{extra}); keep the empirical model")
    if gain >= 5 and (not has_test or vgain >= 5):
        return Verdict("better", f"{target}: the {what} beats the empirical model by {gain:.0f} % {where} "
                                 f"({errs}{extra})")
    if gain >= 5:
        return Verdict("no better", f"{target}: the {what} is better {where} ({gain:+.0f} %: {errs}) but not "
                                    f"in validation on the training flights ({vgain:+.0f} %): keep the empirical model")
    if gain > -5:
        return Verdict("no better", f"{target}: the {what} is no better than the empirical model {where} "
                                    f"({gain:+.0f} %: {errs}): keep the empirical model")
    why = ("the training flights do not represent the test flights" if has_test else
           "its fitted terms do not hold across the validation blocks")
    return Verdict("worse", f"{target}: the {what} is WORSE than the empirical model {where} ({gain:+.0f} %: "
                            f"{errs}{extra}): {why}; keep the empirical model")


def summarise_target(p: TargetProblem, cfg: IdentifyConfig, runs: Sequence[RunRecord | None],
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
        identified = best.summary(("rmse_train", "rmse_test", "constraint_rmse_train",
                                   "constraint_rmse_test", "seed", "qualified"))
        median = {k: finite_median(getattr(r, k) for r in done)
                  for k in (*metric, "constraint_rmse_train")}
        pred = np.asarray(best.pred_test, float)
    else:
        identified = {k: nan for k in metric}
        median = {k: nan for k in metric}
        pred = np.full(len(p.test), nan)
    notes = [p.test_description, *p.notes]
    if best is not None and not best.qualified and not p.ladder:
        notes.append(f"no run met the constraint threshold e_c^train < {cfg.gamma}: the run with "
                     f"the lowest training constraint error is reported instead")
    if errors:
        notes.append(f"{len(errors)} run(s) failed: " + "; ".join(f"run {i + 1}: {e}" for i, e in errors.items()))
    final, guards = _final_rung(p, cfg, done) if p.ladder else (None, {})
    if final is not None:
        identified = {"rmse_train": final["rmse_train"], "rmse_test": final["rmse_test"],
                      "rmse_validation": final["rmse_validation"],
                      "constraint_rmse_test": final["constraint_rmse_test"],
                      "constraint_rmse_train": identified.get("constraint_rmse_train", nan),
                      "seed": done[guards["chosen_run"]].seed if guards.get("chosen_run") is not None else None,
                      "qualified": identified.get("qualified", True)}
        pred = np.asarray(final["pred_test"], float)
        if math.isfinite(final["constraint_rmse_test"]) and final["constraint_rmse_test"] > cfg.gamma:
            notes.append(f"the final model breaks the prior's formal constraints (e_c = "
                         f"{final['constraint_rmse_test']:.3g} m/s² > γ = {cfg.gamma:g}): the data pull its "
                         f"fitted scales away from the physics where there are no data (e.g. zero thrust); "
                         f"trust it inside the training range only")
        if guards.get("implausible"):
            notes.append(f"{guards['implausible']} run(s) rejected: their model leaves ±{guards['bound']:.3g} "
                         f"{'m/s²' if p.target.startswith('v') else ''} on the training inputs' range ± 20 %")
    imp = {"vs_empirical": improvement_pct(p.empirical["rmse_test"], identified["rmse_test"]),
           "vs_empirical_refit": improvement_pct(p.empirical_refit["rmse_test"], identified["rmse_test"]),
           "median_vs_empirical": improvement_pct(p.empirical["rmse_test"], median["rmse_test"])}
    series = {k: np.asarray(v).tolist() for k, v in p.series.items()}
    series["identified"] = pred.tolist()
    series["sources"] = list(p.test.sources)
    ladder = [{k: v for k, v in r.items() if k != "pred_test"} for r in [*p.ladder, *([final] if final else [])]]
    if final is not None:
        notes.extend(final.get("evidence", ()))
    evolved = bool(final and guards.get("chosen_run") is not None)
    vd = verdict(p.target, final, p.ladder[0], evolved, p.holdout, float(np.std(p.train.y)),
                 reference=p.ladder[1] if len(p.ladder) > 1 else None, gamma=cfg.gamma) if final else None
    equation = None
    if final is not None:
        parts = []
        for lab, c in final["terms"].items():
            lead = _LEADING_NUMBER.match(lab)
            if lead:  # 1.085e-10·4*roll**2 -> 4.34e-10·roll**2
                c, lab = c * float(lead.group(1)), lab[lead.end():]
            parts.append(f"{c:+.4g}·{lab}")
        if final.get("intercept") is not None and final["intercept"] != 0:
            parts.append(f"{final['intercept']:+.4g}")
        equation = f"{p.target} = " + " ".join(parts).lstrip("+")
    return TargetResult(
        ladder=ladder, final=final["model"] if final else None,
        empirical_model=p.ladder[0]["model"] if p.ladder else None,
        refit_model=p.ladder[1]["model"] if len(p.ladder) > 1 else None,
        verdict=str(vd) if vd else "", verdict_kind=vd.kind if vd else "",
        guards=guards,
        target=p.target, inputs=list(p.train.input_names), n_train=len(p.train), n_test=len(p.test),
        test_data=p.test_description, holdout=p.holdout, prior_features=_feature_dicts(feats),
        empirical_terms=_feature_dicts(p.priors3),
        equation=equation or (readable_equation(p.target, best.coefficients, best.prior_coefficients,
                                                best.intercept, best.prior_symbols) if best else None),
        equation_expanded=(final["model"]["equation"] if final else
                           f"{p.target} = {best.equation_expanded or best.equation}" if best else None),
        coefficients=({k: v for k, v in final["terms"].items() if not k.startswith("⟨")} if final
                      else dict(best.coefficients) if best else {}),
        prior_coefficients=({k.strip("⟨⟩"): v for k, v in final["terms"].items() if k.startswith("⟨")}
                            if final else dict(best.prior_coefficients) if best else {}),
        intercept=final.get("intercept") if final else best.intercept if best else None,
        identified=identified, identified_median=median,
        empirical=dict(p.empirical), empirical_refit=dict(p.empirical_refit), improvement_pct=imp,
        runs=[r.summary() for r in done],
        best_run=best_i, failed_runs={str(k): v for k, v in (errors or {}).items()},
        model=best.model if best else None, test_series=series, notes=notes,
        intervals={k.strip("⟨⟩"): v for k, v in (final or {}).get("intervals", {}).items()},
        input_ranges={n: [float(np.min(p.train.X[:, i])), float(np.max(p.train.X[:, i]))]
                      for i, n in enumerate(p.train.input_names)} if len(p.train) else {},
        screened={"training": dict(p.train.screened),
                  **({"test": dict(p.test.screened)} if len(p.test) and not p.holdout else {})})


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
    horizons: dict = field(default_factory=dict)   # multi-step prediction on the test flights

    def to_dict(self) -> dict:
        return to_jsonable({
            "schema": SCHEMA,
            "targets": {k: asdict(v) if isinstance(v, TargetResult) else v for k, v in self.targets.items()},
            "config": self.config, "provenance": self.provenance, "versions": self.versions,
            "interrupted": self.interrupted, "wall_s": self.wall_s, "backend": self.backend,
            "notes": self.notes, "horizons": self.horizons})

    @classmethod
    def from_dict(cls, d: dict) -> "IdentificationResult":
        if not isinstance(d, dict) or "targets" not in d:
            raise DataError("not an identification result (no 'targets')")
        names = {f.name for f in fields(TargetResult)}
        targets = {k: TargetResult(**{n: v.get(n) for n in names}) for k, v in d["targets"].items()}
        return cls(targets, d.get("config", {}), d.get("provenance", {}), d.get("versions", {}),
                   bool(d.get("interrupted", False)), float(d.get("wall_s") or 0.0),
                   d.get("backend", ""), list(d.get("notes", [])), dict(d.get("horizons") or {}))


def versions() -> dict:
    import numpy
    import scipy
    import sympy
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
    cfg = (config or IdentifyConfig()).validated()
    if not train_flights:
        raise DataError("no training flights")
    t0 = time.perf_counter()
    prior, _ = resolve_plan_prior(cfg, train_flights)
    targets = targets_for(prior, cfg.targets)
    fitness = {"train": check_prior_data(train_flights, prior, targets, cfg.ts, "training")}
    if test_flights:
        fitness["test"] = check_prior_data(test_flights, prior, targets, cfg.ts, "test")
    cuts = None
    if not test_flights and cfg.test_fraction > 0:
        first = targets[0]
        cuts = holdout_cuts(train_flights, cfg, first, prior)
    plan = plan_identification(train_flights, cfg, progress, cuts)
    cfg = replace(cfg, targets=plan.targets)
    problems = {t: prepare_target(train_flights, test_flights, t, cfg, plan, cuts) for t in cfg.targets}
    jobs = [j for t in cfg.targets for j in make_jobs(problems[t], cfg)]
    _compile_once(progress)
    outcome = runner.run_jobs(run_job, jobs, n_jobs=cfg.jobs, scheduler=cfg.scheduler, progress=progress,
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
    notes = [f"prior: {plan.prior.name} ({plan.prior_reason})", *plan.notes,
             *(f"data ({role}): {w}" for role, f in fitness.items() if f is not None
               for w in _grouped(f.warnings))]
    if outcome.interrupted:
        notes.append(f"interrupted: {outcome.n_done} of {len(jobs)} runs finished and are reported")
    prov = {"train": flight_provenance(train_flights), "test": flight_provenance(test_flights or [])}
    conf = cfg.to_dict()
    conf.update(validation=next(iter(problems.values())).validation, prior_used=plan.prior.name, prior_params=dict(plan.prior.params), prior_reason=plan.prior_reason,
                delays_s=dict(plan.delays_s), delay_scores={f"{k:.2f}": v for k, v in plan.delay_scores.items()},
                offset=({"offset_s": plan.offset.offset_s, "interval_s": list(plan.offset.interval_s),
                         "evidence": plan.offset.decision.evidence if plan.offset.decision else ""}
                        if plan.offset is not None else None),
                diagnosis=plan.diagnosis,
                fitness={role: f.to_dict() for role, f in fitness.items() if f is not None})
    horizons = _horizons(targets, test_flights, notes) if test_flights else {}
    return IdentificationResult(targets, conf, prov, versions(), outcome.interrupted,
                                time.perf_counter() - t0, outcome.backend, notes, horizons)


def _grouped(warnings) -> list[str]:
    """Per-flight warnings ``"name: text"`` with the same text said once, naming every flight."""
    by_text: dict[str, list[str]] = {}
    for w in warnings:
        name, sep, text = w.partition(": ")
        by_text.setdefault(text if sep else w, []).append(name if sep else "")
    return [f"{', '.join(n for n in names if n)}: {text}" if any(names) else text
            for text, names in by_text.items()]


def _compile_once(progress: Callable | None) -> None:
    """Compile the SNGP kernels here, once, when numba's cache lacks them (a fresh clone without
    ``make install``), so the workers load them instead of each compiling at once; says so."""
    if kernels_ready():
        return
    if progress:
        progress(0, 1, "compiling the SNGP kernels (first run only, ~20 s)…")
    s = warmup()
    log.info("SNGP kernels compiled in %.1f s", s)


def _horizons(targets: dict, flights, notes: list, steps=(1, 10, 50)) -> dict:
    """Multi-step prediction of the final, empirical and refit models on the test flights
    (:func:`droneid.rollout.horizon_section`); {} with a note when it cannot be done."""

    def models(key):
        return {t: IdentifiedModel.from_dict(getattr(tr, key)) for t, tr in targets.items()
                if isinstance(tr, TargetResult) and getattr(tr, key)}
    try:
        return horizon_section(models("final"), models("empirical_model"), models("refit_model"),
                               list(flights), horizons=steps)
    except (ConfigError, DataError) as exc:
        notes.append(f"no multi-step prediction on the test flights: {exc}")
        return {}
