"""The problem stage of identify: one target's datasets, prior features, constraint samples and
physical rungs, built once from the plan (:mod:`droneid.planning.plan`) and shared by every SNGP run
(:mod:`droneid.identify.search`) and the guards (:mod:`droneid.identify.ladder`).

- :func:`prepare_target` builds a :class:`TargetProblem`;
- :func:`constraint_sets` chooses the constraint set a target's runs train on and the one e_c
  is measured against;
- :func:`empirical_model` is the user's empirical model as given (the baseline of every verdict).

Errors are RMSEs in the target's units (m/s² for v̇).
"""
from __future__ import annotations

import inspect
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import sympy as sp

from priors import constraints as pc
from priors.registry import PRIORS, get_prior, resolve_prior

from droneid.dataset.data import Dataset
from droneid.errors import ConfigError, DataError
from droneid.fitting.closed_form import IdentifiedModel
from droneid.identify.ladder import fitted_thrust, physical_rungs
from droneid.planning.plan import Plan, dataset_builder, fixed_plan, holdout_cuts, train_rows
from droneid.identify.search import run_seeds
from droneid.core.targets import HORIZONTAL, velocity_of
from droneid.fitting.terms import defined_rows, defined_samples, split_terms
from droneid.dataset.validation import validation_blocks

__all__ = ["TargetProblem", "prepare_target", "constraint_sets", "empirical_prior", "empirical_model",
           "range_notes"]

log = logging.getLogger(__name__)


@dataclass
class TargetProblem:
    """Everything the runs of one target share (lives in memory only; built by :func:`prepare_target`).

    train, test : the datasets (test: empty without test flights or a held-out block)
    priors3 : the prior's terms and the folded effects' features (``priors3[:n_base]`` the prior's)
    prior1 : the prior as one feature; constraint_set : the set the constrained runs train on;
    eval_constraint_set : the one e_c is measured against (the prior's own when runs are
    unconstrained); cs_test : its samples for e_c^test, common to every run
    empirical, empirical_refit, series : errors and test predictions of the first two rungs
    plan : the :class:`~droneid.planning.plan.Plan` it was built from; ladder : its physical
    :class:`~droneid.identify.ladder.Rung` s (empirical, refit, offset, effects); blocks, validation : the
    training rows' validation blocks and how they were made; notes : sentences for the result
    train_at : ((offset s, Dataset, the training rows it shares), ...) the thrust inputs read at each
        other offset the data admit (:meth:`~droneid.planning.plan.Plan.admitted_offsets`): the
        vehicle constants' intervals span their refits there
    """
    target: str
    train: Dataset
    test: Dataset
    test_description: str
    holdout: bool
    priors3: tuple
    prior1: tuple
    constraint_set: object | None
    eval_constraint_set: object | None
    cs_test: object | None
    empirical: dict = field(default_factory=dict)
    empirical_refit: dict = field(default_factory=dict)
    series: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    plan: Plan | None = None
    n_base: int = 0
    ladder: list = field(default_factory=list)
    blocks: np.ndarray | None = None
    validation: str = ""
    train_at: tuple = ()


def constraint_sets(cfg, target: str, prior=None, train: Dataset | None = None):
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
                   cfg, plan: Plan | None = None, cuts: dict | None = None) -> TargetProblem:
    """Build the train/test datasets, priors, constraint samples and the physical rungs of one
    target (``cfg``: the identify config; ``cuts``: the hold-out starts of
    :func:`droneid.planning.plan.holdout_cuts`, without test flights)."""
    if plan is None:
        plan = fixed_plan(cfg, (target,))
    if not test_flights and cfg.test_fraction > 0 and cuts is None:
        cuts = holdout_cuts(train_flights, cfg, target, plan.prior)
    prior = plan.prior
    effect_feats = tuple(f for e in plan.effects for f in e.features.get(target, ()))
    base = split_terms(prior, target)
    extra_inputs = sorted({s for f in effect_feats for s in f.signals} - set(prior.inputs(target)))
    inputs = tuple(prior.inputs(target)) + tuple(extra_inputs)
    empirical_inputs = _empirical_inputs(cfg, target)
    # the empirical model's inputs the prior lacks must exist on every row (explicit extras cut
    # the rows at their gaps); without any, the plan's own request: its datasets are reused
    extras = [s for s in empirical_inputs if s not in inputs] or None
    builder = dataset_builder(cfg, plan.delays_s)
    ds = builder.build(list(train_flights), target=target, inputs=inputs,
                       extras=extras)
    holdout = not test_flights and cfg.test_fraction > 0
    if test_flights:
        train = ds
        test = builder.build(list(test_flights), target=target, inputs=inputs,
                             extras=extras)
        desc = f"test flights: {', '.join(test.sources) or len(test_flights)}"
    elif holdout:
        train, test = train_rows(ds, cuts), train_rows(ds, cuts, test=True)
        desc = (f"no test flights given: the last {100 * cfg.test_fraction:.0f} % (time block) of "
                f"each training flight is held out as test data, before any choice is made")
    else:
        train, test = ds, ds.subset(np.zeros(len(ds), bool))
        desc = ("no test flights given: all training data are used; the errors out of sample are the "
                "validation column (give --test LOG for a transfer check, or --holdout 0.3)")
    dropped: list[str] = []
    train, test = (_finite_rows(d, base + effect_feats, what, dropped) for d, what in ((train, "training"), (test, "test")))
    for name, d in (("training", train), ("test", test)):
        if len(d) < 10 and (name == "training" or test_flights or holdout):
            raise DataError(f"the {name} data for {target} have only {len(d)} samples (need >= 10)")
    priors3 = base + effect_feats
    prior1 = tuple(prior.features(target, 1))
    train_set, eval_set = constraint_sets(cfg, target, prior, train)
    test_seed, _ = run_seeds(cfg.seed, 0)
    cs_test = None
    if eval_set is not None:
        cs_test, n_undefined = defined_samples(
            eval_set.sample(list(train.input_names), n_per_constraint=cfg.n_constraint_samples, seed=test_seed),
            priors3)
        if n_undefined:
            dropped.append(f"{n_undefined} constraint sample(s) left out: a prior or effect feature is not "
                           f"finite there (e.g. a share of thrust at zero rotor speed)")
    p = TargetProblem(target, train, test, desc, holdout, priors3, prior1, train_set, eval_set, cs_test,
                      plan=plan, n_base=len(base))
    p.notes.extend(dropped)
    if eval_set is None and cfg.constraints != "none":
        p.notes.append(f"prior '{prior.name}' defines no constraints for {target}: the runs are "
                       f"unconstrained and e_c is not measured (give --constraints FILE.toml)")
    if len(test):
        p.notes.extend(range_notes(train, test))
    undelayed = None
    if plan.delays_s:
        b0 = dataset_builder(cfg)
        tr0 = b0.build(list(train_flights), target=target, inputs=inputs,
                       extras=extras)
        undelayed = (tr0, b0.build(list(test_flights), target=target, inputs=inputs,
                                   extras=extras)) \
            if test_flights else (train_rows(tr0, cuts), train_rows(tr0, cuts, test=True) if holdout
                                  else tr0.subset(np.zeros(len(tr0), bool)))
        # every rung is measured on the same rows: those the delayed inputs exist for
        undelayed = tuple(_same_rows(u, d) for u, d in zip(undelayed, (train, test)))
    p.train_at = _train_at(plan, cfg, train_flights, target, inputs, extras, cuts, holdout, train, base + effect_feats)
    _ladder(p, cfg, undelayed)
    return p


def _train_at(plan: Plan, cfg, train_flights, target, inputs, extras, cuts, holdout, train, feats) -> tuple:
    """((offset s, training Dataset at it, ``train`` on the same rows), ...) at each offset of
    :meth:`Plan.admitted_offsets` other than the chosen one: the rows both readings have (an
    offset moves the signals' gaps and ends), so a refit compares the readings, not the rows."""
    out = []
    for d in plan.admitted_offsets():
        ds = dataset_builder(cfg, {s: d for s in plan.thrust_signals}).build(
            list(train_flights), target=target, inputs=inputs, extras=extras)
        ds = train_rows(ds, cuts) if holdout else ds
        ds = _same_rows(_finite_rows(ds, feats, "training", []), train)
        if len(ds) > 10:
            out.append((d, ds, _same_rows(train, ds)))
    return tuple(out)


def _ladder(p: TargetProblem, cfg, undelayed: tuple | None) -> None:
    """The physical rungs of ``p`` (:func:`droneid.identify.ladder.physical_rungs`) with their summary
    (p.empirical, p.empirical_refit, p.series) and a note when the fitted thrust is not positive."""
    p.blocks, p.validation = validation_blocks(p.train.t, p.train.flight)
    p.ladder = list(physical_rungs(p, empirical_model(cfg, p.target), undelayed))
    lift = fitted_thrust(p, p.ladder[-1].terms)
    if lift is not None and not lift > 0:
        p.notes.append(f"the fitted thrust is not positive over the training data (median {lift:.3g} m/s²): "
                       f"these data cannot separate thrust from gravity and drag (e.g. a flight at constant "
                       f"height); this {p.target} model is not physical")
    e0, r1 = p.ladder[0], p.ladder[1]
    p.empirical = {"rmse_train": e0.rmse_train, "rmse_test": e0.rmse_test,
                   "constraint_rmse_test": e0.constraint_rmse_test,
                   "equation": f"{e0.model.target} = {e0.model.text()}", "expr": e0.model.to_dict()["expr"]}
    p.empirical_refit = {"rmse_train": r1.rmse_train, "rmse_test": r1.rmse_test,
                         "constraint_rmse_test": r1.constraint_rmse_test,
                         "coefficients": {k.strip("⟨⟩"): v for k, v in r1.terms.items()},
                         "intercept": r1.intercept}
    p.series = {"t": p.test.t, "flight": p.test.flight, "y": p.test.y, "empirical": e0.pred_test,
                "empirical_refit": r1.pred_test if len(r1.pred_test) == len(p.test) else
                p.ladder[-1].pred_test}


def _finite_rows(ds: Dataset, features, what: str, notes: list) -> Dataset:
    """``ds`` without the rows where a prior or effect feature is not finite (e.g. a thrust share
    with every motor stopped for a sample), counted in ``notes``: no fit or SNGP run may see them."""
    if not len(ds):
        return ds
    ok, bad = defined_rows(features, ds.columns(), len(ds))
    if ok.all():
        return ds
    notes.append(f"{int((~ok).sum())} {what} row(s) left out: a prior or effect feature is not finite "
                 f"there ({', '.join(bad)}; e.g. a share of thrust with every motor stopped)")
    return ds.subset(ok)


def _same_rows(ds: Dataset, like: Dataset) -> Dataset:
    """The rows of ``ds`` (same grid, more rows) that ``like`` has: same flight and time."""
    key = lambda d: d.flight.astype(np.int64) * 10**9 + np.round(d.t * 1e4).astype(np.int64)  # noqa: E731
    return ds.subset(np.isin(key(ds), key(like)))


def empirical_prior(cfg):
    """The prior behind the user's empirical model (``cfg.empirical``: a built-in name or
    ``FILE.toml:NAME``), with ``cfg.k_D`` when the prior takes a drag constant."""
    if cfg.empirical in PRIORS and "k_D" in inspect.signature(PRIORS[cfg.empirical]).parameters:
        return get_prior(cfg.empirical, k_D=cfg.k_D)
    return resolve_prior(cfg.empirical)


def _empirical_inputs(cfg, target: str) -> tuple:
    m = empirical_prior(cfg)
    return m.signals(target) if target in m.targets else ()


def empirical_model(cfg, target: str):
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

