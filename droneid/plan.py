"""The plan of an identification: every choice made from the TRAINING flights before any SNGP run.

:func:`plan_identification` picks the prior (``auto``: the most physical one the logs' signals
support, :func:`priors.models.prior_for`), sets the rotor-thrust prior's nominal thrust scale by
hover balance, chooses the input delay of the thrust signals by blocked cross-validation
(:func:`droneid.ladder.choose_delay`) and runs the diagnosis (:mod:`droneid.diagnose`) to find the
effects to fold into the prior features. Rows held out as test data (``cuts``) are never seen.
The result is a frozen :class:`Plan`; :mod:`droneid.identify` builds the target problems from it.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from priors.models import PriorFeature, get_prior, prior_for, resolve_prior

from .data import Dataset
from .dataset_builder import DatasetBuilder, split_time_block
from .diagnose import DiagnoseConfig, diagnose_datasets
from .errors import ConfigError, DataError
from .fitness import usable_signals
from .ladder import TermModel, block_ids, choose_delay, n_blocks_for
from .targets import targets_for

__all__ = ["Plan", "plan_identification", "holdout_cuts", "resolve_plan_prior", "train_rows",
           "thrust_signals", "split_terms", "prior_terms", "dataset_builder", "fixed_plan", "PAPER_PRIOR"]

#: the prior of the paper's protocol (``study``, and ``--prior auto`` without a plan)
PAPER_PRIOR = "tilt-drag"


@dataclass(frozen=True)
class Plan:
    """What identify decided from the TRAINING flights before any SNGP run.

    prior : the PriorModel the search starts from; prior_reason : why (for ``auto``)
    targets : the targets identified; delays_s : {signal: delay s} of the thrust inputs
    delay_scores : {delay s: joint blocked-CV error of the refit prior} (the evidence)
    effects : the diagnosis' folded effects: [{"effect", "physical", "features": {target:
        [PriorFeature]}}]; not_folded : [{"effect", "reason"}]; diagnosis : its summary dict
    """
    prior: object
    prior_reason: str
    targets: tuple
    delays_s: dict = field(default_factory=dict)
    delay_scores: dict = field(default_factory=dict)
    effects: tuple = ()
    not_folded: tuple = ()
    diagnosis: dict = field(default_factory=dict)
    notes: tuple = ()


def _hover_calibrated(prior, flights, cfg, cuts=None):
    """The rotor-thrust prior with its nominal thrust scale k_T set by hover balance on the
    training rows: the median of k_T·thrust·cosφ·cosθ is g (uses inputs only, no derivative),
    so the fitted scales read as ~1 and the 1-feature form is a sensible model as given."""
    t = "vz_dot"
    ds = train_rows(dataset_builder(cfg).build(list(flights), target=t, inputs=prior.inputs(t)), cuts)
    thrust = [f for f in prior.features(t) if f.role == "thrust"]
    k_T = float(prior.params["k_T"])
    lift = sum(prior.evaluate(ds.columns(), t)[:, i] for i, f in enumerate(prior.features(t)) if f.role == "thrust")
    med = float(np.median(lift)) / k_T if thrust and len(ds) else 0.0
    if not med > 0:
        return prior
    params = {k: v for k, v in prior.params.items() if k != "k_T"}
    return get_prior("rotor-thrust", k_T=float(prior.params.get("g", 9.81)) / med, **params)


def resolve_plan_prior(cfg, flights) -> tuple:
    """(PriorModel, reason) for the config's prior on these flights (``auto`` picks)."""
    return prior_for(cfg.prior, usable_signals(flights, cfg.ts))


def thrust_signals(prior, target: str) -> list:
    return sorted({s for f in prior.features(target) if f.role == "thrust" for s in f.signals
                   if s not in ("roll", "pitch", "yaw")})


def dataset_builder(cfg, delays=None):
    """The DatasetBuilder of an identify config (its Ts and differentiator), with input delays."""
    return DatasetBuilder(ts=cfg.ts, method=cfg.method, delays_s=dict(delays or {}))


def split_terms(prior, target: str) -> tuple:
    """The prior's terms as separate features, without constant ones (the intercept holds them,
    or the prior's fixed offset when the constant is known physics: gravity)."""
    return tuple(f for f in prior.features(target) if f.expr.free_symbols)


def prior_terms(prior, target: str, features: Sequence | None = None) -> TermModel:
    """The unfitted refit model of ``target``: the prior's terms (or ``features``: its terms and
    effects) with their physical bounds, its fixed offset (gravity) and its intercept bounds."""
    feats = split_terms(prior, target) if features is None else tuple(features)
    return TermModel.of(feats, intercept_bounds=prior.intercept_bounds(target), offset=prior.offset(target))


def fixed_plan(cfg, targets: Sequence[str] | None = None) -> Plan:
    """The plan of the paper's protocol, decided without looking at data: the named prior
    (``auto``: :data:`PAPER_PRIOR`), no input delays, no folded effects; ``targets`` (default:
    the config's, else every vehicle target the prior models)."""
    prior = resolve_prior(PAPER_PRIOR if cfg.prior == "auto" else cfg.prior)
    why = "the paper's prior" if cfg.prior == "auto" else "named by the user"
    return Plan(prior, why, targets_for(prior, targets or cfg.targets))


def plan_identification(train_flights, cfg, progress: Callable | None = None,
                        cuts: dict | None = None) -> Plan:
    """Choose the prior, the thrust input delay and the effects from the training flights only
    (``cuts``: {flight index: time s} where a held-out test block starts: rows from there on
    are never seen here)."""
    prior, reason = resolve_plan_prior(cfg, train_flights)
    if prior.name == "rotor-thrust":
        prior = _hover_calibrated(prior, train_flights, cfg, cuts)
    targets = targets_for(prior, cfg.targets)
    notes = []
    thrust = sorted({s for t in targets for s in thrust_signals(prior, t)})
    delays, scores = {}, {}
    if cfg.delays == "auto" and thrust:
        cache = {}

        def cv_error(d):
            total = 0.0
            for t in targets:
                ds = train_rows(dataset_builder(cfg, {s: d for s in thrust}).build(
                    list(train_flights), target=t, inputs=prior.inputs(t)), cuts)
                tm = prior_terms(prior, t)
                blocks = block_ids(ds.t, ds.flight, n_blocks_for(len(ds)))
                e = tm.cv_rmse(ds.columns(), ds.y, blocks)
                base = cache.setdefault(t, e)  # d = 0 comes first: errors relative to no delay
                total += e / base
            return total / len(targets)
        if progress:
            progress(0, 1, "choosing the thrust input delay")
        best, scores = choose_delay(cv_error)
        if best:
            delays = {s: best for s in thrust}
            notes.append(f"thrust inputs ({', '.join(thrust)}) delayed by {1000 * best:.0f} ms: blocked-CV "
                         f"error of the refit prior {100 * (1 - scores[best] / scores[0.0]):.1f} % lower "
                         f"than without delay (training flights only)")
    effects, not_folded, diag = (), (), {}
    if cfg.effects == "auto":
        effects, not_folded, diag, enotes = _diagnosed_effects(train_flights, prior, targets, cfg, delays, cuts)
        notes.extend(enotes)
    return Plan(prior, reason, targets, delays, scores, effects, not_folded, diag, tuple(notes))


def train_rows(ds: Dataset, cuts: dict | None, test: bool = False) -> Dataset:
    """The rows before each flight's hold-out cut (``test``: from the cut on); all without cuts."""
    if not cuts:
        return ds
    cut = np.array([cuts.get(int(k), np.inf) for k in range(int(ds.flight.max()) + 1)]) if len(ds) else []
    before = ds.t < cut[ds.flight] if len(ds) else np.zeros(0, bool)
    return ds.subset(~before if test else before)


def holdout_cuts(train_flights, cfg, target: str, prior) -> dict:
    """{flight index: start time s of its held-out last ``cfg.test_fraction``} (time-block split
    of the undelayed dataset of ``target``)."""
    ds = dataset_builder(cfg).build(list(train_flights), target=target, inputs=prior.inputs(target))
    _, test = split_time_block(ds, test_fraction=cfg.test_fraction)
    return {int(k): float(np.min(test.t[test.flight == k])) for k in np.unique(test.flight)}


def _diagnosed_effects(train_flights, prior, targets, cfg, delays, cuts=None):
    """Effects the diagnosis adds on the TRAINING flights, as prior features to fold in."""
    builder = dataset_builder(cfg, delays)
    train = {t: train_rows(builder.build(list(train_flights), target=t, inputs=prior.inputs(t)), cuts)
             for t in targets}
    try:
        res = diagnose_datasets(train, None, prior=prior,
                                config=DiagnoseConfig(ts=cfg.ts, method=cfg.method, generations=0))
    except (ConfigError, DataError, TypeError) as exc:
        return (), (), {}, [f"diagnosis skipped: {exc}"]
    folded, skipped = [], []
    for fe in res.final_effects:
        feats = fe.get("features")
        if fe.get("foldable") and feats:
            folded.append({"effect": fe["effect"], "physical": fe.get("physical", ""),
                           "features": {t: tuple(PriorFeature(d["name"], d["expr"], fe.get("physical", ""),
                                                              "other") for d in feats.get(t, ()))
                                        for t in targets}})
        else:
            skipped.append({"effect": fe["effect"], "physical": fe.get("physical", ""),
                            "reason": fe.get("reason") or "not foldable into a model of states and inputs"})
    summary = {"effects_added": list(res.effects_added), "conclusion": res.conclusion,
               "untestable": dict(res.untestable), "not_detected": list(res.not_detected)}
    notes = [f"diagnosis on the training flights: {res.conclusion}"]
    notes += [f"effect {s['effect']} ({s['physical']}) not folded into the model: {s['reason']}" for s in skipped]
    return tuple(folded), tuple(skipped), summary, notes
