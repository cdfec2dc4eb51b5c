"""Diagnosis: find what a prior model lacks, in physical terms, with out-of-sample evidence.

Pipeline (:func:`diagnose` from flights, :func:`diagnose_datasets` from Datasets):

1. Fit the prior as given (every feature weight 1) and refit it by least squares WITHOUT an
   intercept (a free intercept would absorb wind and attitude biases), jointly for all targets;
   the residual is what the refit prior leaves.
2. Score every testable effect of the catalogue (:mod:`priors.effects`) by BLOCKED
   cross-validation: each training flight is cut into ``n_blocks`` contiguous time blocks; the
   model with and without the effect is fitted on all blocks but one and predicts the held-out
   one. Effects are fitted jointly over the targets: a parameter shared by v̇x and v̇y (quadratic
   drag c, attitude biases, delay τ) is one coefficient.
3. Add the best effect only if the one decision rule accepts it (:func:`droneid.decide.decide`):
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
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import sympy as sp

from priors.effects import CATALOGUE, EffectContext, is_measured_derivative
from priors.models import PriorFeature, PriorModel, prior_for, resolve_prior

from .data import Dataset
from .dataset_builder import DatasetBuilder
from .differentiation import DIFFERENTIATORS
from .errors import ConfigError, DataError, MissingSignalError, check_choice, did_you_mean
from .expressions import compile_expression, symbol
from .fitness import check_prior_data, usable_signals
from .io_util import to_jsonable
from .decide import Decision, decide
from .ladder import block_ids
from .numerics import lstsq, rmse
from .sngp import SNGPRegressor
from .targets import targets_for, velocity_of

log = logging.getLogger(__name__)

__all__ = ["DiagnoseConfig", "DiagnosisResult", "diagnose", "diagnose_datasets", "evidence_of",
           "block_ids", "NO_FURTHER", "fold_into_prior", "choose_diagnose_prior", "build_datasets"]

NO_FURTHER = "no further effect is detectable from these signals"
_ANGLES = ("roll", "pitch")
#: prior term roles whose sum is the effects' G (thrust direction / logged thrust)
_G_ROLES = ("tilt", "thrust")
# signals never offered to the open-ended search (absolute horizontal position, which would let
# it fit a map of the training flight; redundant attitude parametrisation; derived duplicates)
_OPEN_EXCLUDE = {"lat", "lon", "alt", "x", "y", "qw", "qx", "qy", "qz", "v_axis", "t"}


@dataclass(frozen=True)
class DiagnoseConfig:
    """Settings of a diagnosis (docs/diagnosis.md documents them).

    ts, method: dataset grid step and differentiator (central differences by default: forward
        differences shift the target by Ts/2, which would look like an attitude delay).
    n_blocks: contiguous time blocks per training flight for cross-validation; None (default):
        :func:`diagnose_blocks` (``clip(n_train // 60, 16, 30)``, n_train the training samples
        per target: blocks of ~60 samples, 3 s at 20 Hz).
    alpha: family-wise error level of the decision rule over every candidate the diagnosis may
        try (Holm; :mod:`droneid.decide`).
    min_rel_improvement: minimum relative CV-RMSE improvement for an effect to count.
    pair_min_gain: when no single effect passes, the best single's relative CV gain from which
        pairs of candidates are tested jointly (overlapping effects); pair_top: how many of the
        best singles form the pairs.
    allow_measured_derivatives: let effects and the open-ended search use measured derivatives
        (IMU ax ay az, differenced vz_dot); the result then says the model cannot be simulated.
    max_steps: most effects added (a joint pair counts as one step).
    ground_h0_m, ground_z_m: decay height (m) of the ground effect and the known ground height (m,
        0: the frame's origin is on the floor or at the take-off point).
    effects: restrict the catalogue to these ids (None: all); user_effects: extra Effect objects.
    generations: budget of the open-ended search per run (0 disables it).
    """
    ts: float = 0.05
    method: str = "central"
    n_blocks: int | None = None
    alpha: float = 0.01
    min_rel_improvement: float = 0.01
    pair_min_gain: float = 0.05
    pair_top: int = 4
    allow_measured_derivatives: bool = False
    max_steps: int = 5
    g: float = 9.81
    ground_h0_m: float = 0.5
    ground_z_m: float = 0.0
    effects: tuple[str, ...] | None = None
    generations: int = 5000
    population_size: int = 500
    n_features: int = 3
    max_depth: int = 5
    seed: int = 0
    max_samples: int = 1500

    def validate(self) -> "DiagnoseConfig":
        if not (self.ts > 0):
            raise ConfigError(f"The 'ts' parameter of DiagnoseConfig must be > 0. Got {self.ts!r} instead.")
        if self.n_blocks is not None and not (isinstance(self.n_blocks, int) and 3 <= self.n_blocks <= 50):
            raise ConfigError("The 'n_blocks' parameter of DiagnoseConfig must be an int in [3, 50]. "
                              f"Got {self.n_blocks!r} instead.")
        if not (0 < self.alpha < 0.5):
            raise ConfigError(f"The 'alpha' parameter of DiagnoseConfig must be in (0, 0.5). Got {self.alpha!r} instead.")
        if not (0 <= self.min_rel_improvement < 1):
            raise ConfigError("The 'min_rel_improvement' parameter of DiagnoseConfig must be in [0, 1). "
                              f"Got {self.min_rel_improvement!r} instead.")
        check_choice("method", self.method, DIFFERENTIATORS, owner="DiagnoseConfig")
        if self.max_steps < 0 or self.generations < 0:
            raise ConfigError("max_steps and generations must be >= 0")
        if not (isinstance(self.pair_top, int) and self.pair_top >= 0):
            raise ConfigError("The 'pair_top' parameter of DiagnoseConfig must be an int >= 0. "
                              f"Got {self.pair_top!r} instead.")
        return self


@dataclass
class DiagnosisResult:
    """The outcome of a diagnosis, as data (``to_dict()`` is the diagnosis.json content).

    targets: {target: {"rmse_prior": {train, test}, "rmse_before": {train, test, cv},
        "rmse_after": {...}, "base_coefficients": {...}, "steps": [...], "open_ended": {...}}}
    steps: the joint steps in order: {"effect", "coefficients", "physical", "rmse": {target:
        {train, test, cv}}, "evidence"}
    effects_added: ids in the order they were added; untestable: {id: "needs ..."};
    not_applicable: {id: why the effect makes no sense for this prior / these targets};
    not_detected: ids tested but not added; conclusion: one sentence.
    final_effects: every added effect in physical terms with the FINAL joint coefficients (a step
        reports the values when it was added; later effects can refine them, e.g. wind after
        quadratic drag), plus ``foldable`` (bool), ``reason`` (why not, else "") and
        ``features``: {target: [{"name": f"{effect}_{param}", "expr": sympy.Expr over canonical
        signals (constants fixed from training), "coefficient": fitted value}]} ({} when not
        foldable). ``to_dict()`` writes the expressions as strings.
    simulable: False when the added effects or a passing open-ended term use a measured
        derivative (only possible with ``allow_measured_derivatives``); notes: such warnings.
    series: per-target arrays for the plots (not in diagnosis.json unless asked for).
    """
    targets: dict
    steps: list
    effects_added: list
    untestable: dict
    not_detected: list
    conclusion: str
    open_ended: dict
    config: dict
    prior: str
    sources: dict
    candidates: list = field(default_factory=list)
    final_effects: list = field(default_factory=list)
    not_applicable: dict = field(default_factory=dict)
    simulable: bool = True
    notes: list = field(default_factory=list)
    series: dict = field(default_factory=dict)

    def to_dict(self, include_series: bool = False) -> dict:
        d = {"targets": self.targets, "effects_added": self.effects_added,
             "untestable": sorted(self.untestable), "untestable_reasons": self.untestable,
             "not_detected": self.not_detected, "conclusion": self.conclusion,
             "steps": self.steps, "final_effects": [_final_effect_json(fe) for fe in self.final_effects],
             "open_ended": self.open_ended, "candidates": self.candidates,
             "not_applicable": self.not_applicable, "simulable": self.simulable,
             "notes": self.notes,
             "prior": self.prior, "config": self.config, "sources": self.sources}
        if include_series:
            d["series"] = self.series
        return to_jsonable(d)

    @classmethod
    def from_dict(cls, d: Mapping) -> "DiagnosisResult":
        """The result back from :meth:`to_dict` (``diagnosis.json``): feature expressions stay
        text; without ``series`` (not saved by default) the report has no time-series figures.
        DataError for a document that is not a diagnosis."""
        if not isinstance(d, Mapping) or not isinstance(d.get("targets"), Mapping) \
                or "effects_added" not in d:
            raise DataError("not a diagnosis result (it needs 'targets' and 'effects_added')")
        sources = d.get("sources") or {}
        return cls(targets=dict(d["targets"]), steps=list(d.get("steps") or []),
                   effects_added=list(d["effects_added"] or []),
                   untestable=dict(d.get("untestable_reasons") or {}),
                   not_detected=list(d.get("not_detected") or []), conclusion=str(d.get("conclusion") or ""),
                   open_ended=dict(d.get("open_ended") or {}), config=dict(d.get("config") or {}),
                   prior=str(d.get("prior") or ""),
                   sources={"train": list(sources.get("train") or []), "test": list(sources.get("test") or [])},
                   candidates=list(d.get("candidates") or []), final_effects=list(d.get("final_effects") or []),
                   not_applicable=dict(d.get("not_applicable") or {}), simulable=bool(d.get("simulable", True)),
                   notes=list(d.get("notes") or []), series=dict(d.get("series") or {}))


def _final_effect_json(fe: dict) -> dict:
    """A final effect with its feature expressions as strings."""
    return {**fe, "features": {t: [{**f, "expr": str(f["expr"])} for f in fs]
                               for t, fs in fe.get("features", {}).items()}}


# -- statistics -----------------------------------------------------------------------------------


def evidence_of(dec: Decision) -> dict:
    """The evidence dict of a diagnosis decision (reported for every candidate, accepted or
    rejected) from a :class:`droneid.decide.Decision`."""
    return {"cv_rmse_before": dec.rmse_without, "cv_rmse_after": dec.rmse_with,
            "rel_improvement": dec.effect_pct / 100.0, "p_value": dec.p_value,
            "p_threshold": dec.threshold, "statistic": dec.statistic, "n_blocks": dec.n_blocks,
            "n_candidates": dec.family_size, "holm_rank": dec.rank,
            "blocks_improved": f"{dec.blocks_better}/{dec.n_blocks}",
            "block_rel_improvements": list(dec.block_differences), "passed": dec.accepted,
            "reasons": list(dec.reasons), "text": dec.evidence}


def _with_test(ev: dict, test_before: float | None, test_after: float | None) -> dict:
    """``ev`` plus the test flights' RMSE before/after, REPORTED only (never part of passing)."""
    rel = (1.0 - test_after / test_before if test_before else 0.0) \
        if test_before is not None and test_after is not None else None
    return {**ev, "test_rmse_before": test_before, "test_rmse_after": test_after,
            "test_rel_improvement": rel}


# -- the prior ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _PriorTerms:
    """One target's prior terms; ``tilt`` = G (sum of role tilt/thrust terms), ``tilt_role``;
    ``drag`` = names of the linear-drag terms; ``velocity`` = the target's velocity signal."""
    names: tuple[str, ...]
    exprs: tuple[sp.Expr, ...]
    tilt: sp.Expr | None
    velocity: str | None
    tilt_role: str = "tilt"
    drag: tuple[str, ...] = ()
    g_parts: tuple[tuple[str, sp.Expr], ...] = ()

    def fitted(self, target: str, beta: Mapping[str, float]) -> "_PriorTerms":
        """These terms with G at the scale of a fit: Σ β_term · (the term's G part), so effect
        coefficients read relative to the fitted thrust (a nominal k_T can be far off)."""
        if not self.g_parts:
            return self
        g = sp.Add(*[sp.Float(beta.get(f"{target}:{n}", 1.0)) * e for n, e in self.g_parts])
        return replace(self, tilt=g)


def _prior_features(prior, target: str) -> tuple:
    """All the prior's terms for ``target`` (one feature per term)."""
    for args in ((), (3,), (1,)):
        try:
            feats = tuple(prior.features(target, *args))
        except (ConfigError, ValueError, TypeError):
            continue
        if feats:
            return feats
    raise ConfigError(f"the prior has no features for target '{target}'")


def _prior_terms(prior, target: str) -> _PriorTerms:
    """The prior's terms; G from the terms' roles (``tilt`` or ``thrust``), or for priors
    without roles from the terms containing roll or pitch; drag from the role ``drag`` terms
    (without roles: terms in the target's velocity without angles)."""
    feats = _prior_features(prior, target)
    names = tuple(str(f.name) for f in feats)
    exprs = tuple(f.expr if isinstance(f.expr, sp.Basic) else sp.sympify(f.expr) for f in feats)
    roles = [getattr(f, "role", "other") for f in feats]
    vel = velocity_of(target)
    vsym = symbol(vel) if vel else None
    angle_syms = {symbol(a) for a in _ANGLES}
    if any(r in _G_ROLES for r in roles):
        g_parts = [(n, e) for n, e, r in zip(names, exprs, roles) if r in _G_ROLES]
        role = "thrust" if "thrust" in roles else "tilt"
    else:
        g_parts = [(n, a) for n, e in zip(names, exprs) for a in sp.Add.make_args(sp.expand(e))
                   if a.free_symbols & angle_syms]
        role = "tilt"
    if "drag" in roles:
        drag = tuple(n for n, e, r in zip(names, exprs, roles) if r == "drag" and vsym in e.free_symbols)
    else:
        drag = tuple(n for n, e in zip(names, exprs)
                     if vsym is not None and vsym in e.free_symbols and not e.free_symbols & angle_syms)
    return _PriorTerms(names, exprs, sp.Add(*[e for _, e in g_parts]) if g_parts else None,
                       vel if drag else None, role, drag, tuple(g_parts))


# -- the stacked least-squares problem ------------------------------------------------------------
@dataclass
class _Part:
    """One target's samples of one role (train or test)."""
    target: str
    ctx: object
    y: np.ndarray
    t: np.ndarray
    flight: np.ndarray
    block: np.ndarray
    base: dict           # param -> column (prior features)
    prior_sum: np.ndarray
    role: str = "train"
    sources: tuple = ()

    def flight_label(self, f: int) -> str:
        src = self.sources[f] if f < len(self.sources) else str(f)
        return f"{self.role}:{src}"


def _make_part(ds: Dataset, target: str, terms: _PriorTerms, cfg: DiagnoseConfig, role: str = "train"):
    cols = ds.columns()
    ctx = EffectContext.build(target, cols, ds.t, ds.flight, terms.tilt, cfg.g,
                              {"ground_h0_m": cfg.ground_h0_m, "ground_z_m": cfg.ground_z_m}, terms.tilt_role,
                              cfg.allow_measured_derivatives)
    base = {}
    for name, e in zip(terms.names, terms.exprs):
        missing = [s.name for s in e.free_symbols if s.name not in cols]
        if missing:
            raise MissingSignalError(missing[0], list(cols), where=f"the {target} dataset (prior feature {name})")
        f = compile_expression(e, sorted(s.name for s in e.free_symbols))
        v = np.broadcast_to(f({s.name: cols[s.name] for s in e.free_symbols} or {"_": ds.y}), ds.y.shape)
        base[f"{target}:{name}"] = np.asarray(v, float)
    good = np.isfinite(ds.y)
    for v in base.values():
        good &= np.isfinite(v)
    if not good.all():
        log.warning("%s: dropping %d samples with non-finite target or prior features", target, (~good).sum())
        return _make_part(ds.subset(good), target, terms, cfg, role)
    prior_sum = np.sum(list(base.values()), axis=0)
    blocks = block_ids(ds.t, ds.flight, cfg.n_blocks)
    return _Part(target, ctx, ds.y, ds.t, ds.flight, blocks, base, prior_sum, role, tuple(ds.sources))


class _Stack:
    """Rows of several targets stacked; terms are {param: {target: column}}. ``w``: row weights
    of the least squares and of the CV errors (1/σ of each target's base residual, so a noisy
    target such as v̇z does not dictate a coefficient shared with v̇x, v̇y)."""

    def __init__(self, parts: Sequence[_Part]):
        self.parts = list(parts)
        self.w = np.concatenate([np.ones(p.y.size) for p in parts])
        self.y = np.concatenate([p.y for p in parts])
        self.block = np.concatenate([p.block for p in parts])
        self.tidx = np.concatenate([np.full(p.y.size, i) for i, p in enumerate(parts)])
        self.offsets = np.cumsum([0] + [p.y.size for p in parts])

    def design(self, terms: dict) -> np.ndarray:
        X = np.zeros((self.y.size, len(terms)))
        for j, cols in enumerate(terms.values()):
            for i, p in enumerate(self.parts):
                if p.target in cols:
                    X[self.offsets[i]:self.offsets[i + 1], j] = cols[p.target]
        return X

    def rmse_by_target(self, pred: np.ndarray) -> dict:
        out = {}
        for i, p in enumerate(self.parts):
            r = self.y[self.tidx == i] - pred[self.tidx == i]
            out[p.target] = rmse(r, 0.0)
        return out



def diagnose_blocks(n: int) -> int:
    """Default time blocks per training flight for ``n`` samples: ~60 samples (3 s at 20 Hz) a
    block, 16 to 30 blocks. More blocks than :func:`droneid.ladder.n_blocks_for` because every
    diagnosis decision is a sign-flip test over blocks at a family-wise threshold (α/13 and
    below, 7.7e-4 at α = 0.01): its p is at least 2^−B (2.4e-4 with 12 blocks, which then must
    ALL improve; 1.5e-5 with 16, which leaves room for a block or two that does not)."""
    return int(np.clip(n // 60, 16, 30))


def _lstsq(X, y):
    return lstsq(X, y, rcond=1e-10)

def _cv(stack: _Stack, X: np.ndarray, n_blocks: int):
    """Held-out predictions by leave-one-block-out (weighted least squares); per-block weighted
    MSE and sample counts; the coefficients of every fold (rows; for block-jackknife errors)."""
    pred = np.zeros_like(stack.y)
    w = stack.w
    folds = []
    for k in range(n_blocks):
        test = stack.block == k
        if not test.any():
            continue
        beta = _lstsq(X[~test] * w[~test, None], stack.y[~test] * w[~test])
        folds.append(beta)
        pred[test] = X[test] @ beta
    r2 = (w * (stack.y - pred)) ** 2
    mse = np.array([np.mean(r2[stack.block == k]) if np.any(stack.block == k) else 0.0
                    for k in range(n_blocks)])
    n = np.array([np.sum(stack.block == k) for k in range(n_blocks)])
    return pred, mse, n, np.array(folds)


def _terms_for(effect, parts: Sequence[_Part], consts: Mapping[str, dict] | None = None) -> dict:
    """{param: {target: column}} of an effect over parts, with the constants fixed from training
    (``consts``: {target: {name: value}}); a flight-specific effect (``effect.per_flight``) gets
    one parameter per flight, named ``param@role:source``."""
    terms: dict = {}
    for p in parts:
        if not effect.applies_to(p.target):
            continue
        c = (consts or {}).get(p.target)
        for name, col in effect.features(p.ctx, c).items():
            if getattr(effect, "per_flight", False):
                for f in np.unique(p.flight):
                    terms.setdefault(f"{effect.id}.{name}@{p.flight_label(int(f))}", {})[p.target] = \
                        np.where(p.flight == f, col, 0.0)
            else:
                terms.setdefault(f"{effect.id}.{name}", {})[p.target] = col
    return terms


def _refine(refiners, tr_parts, te_parts, fit, base) -> None:
    """Let each added effect with a refine hook (:meth:`priors.effects.Effect.refine`) update every
    part's context from ``fit``: its coefficients per flight (test flights: their own per-flight
    estimates, else the training ones) and ``base`` (``k_D`` in 1/s). E.g. the wind sets the air
    velocity that drag effects act on."""
    for parts, betas in ((tr_parts, fit["beta"]),
                         (te_parts or [], {**fit["beta"], **fit.get("test_local_beta", {})})):
        for e in refiners:
            own = _split_flight_params({k: v for k, v in betas.items() if k.startswith(e.id + ".")})
            shared = own.get(None, {})
            for p in parts:
                coef = {int(f): {**shared, **own.get(p.flight_label(int(f)), {})}
                        for f in np.unique(p.flight)}
                cols = e.refine(p.ctx, coef, base)
                if cols:
                    p.ctx = p.ctx.with_columns(cols)


def _split_flight_params(coef: Mapping[str, float]) -> dict[str | None, dict]:
    """{flight label or None: {param: value}} from (possibly flight-specific) coefficients."""
    out: dict = {}
    for k, v in coef.items():
        name, _, label = k.partition("@")
        out.setdefault(label or None, {})[name.split(".", 1)[-1]] = v
    return out


def _k_drag(terms: _PriorTerms, target, part: _Part, coef: Mapping[str, float]) -> float | None:
    """Effective linear drag −∂(drag terms)/∂v of a fit (None without a drag term)."""
    if terms.velocity is None:
        return None
    v = symbol(terms.velocity)
    k = 0.0
    for name, e in zip(terms.names, terms.exprs):
        if name in terms.drag:
            de = sp.diff(e, v)
            val = part.ctx.evaluate(de) if de.free_symbols else np.full(part.y.size, float(de))
            k -= coef.get(f"{target}:{name}", 0.0) * float(np.mean(val))
    return k


# -- the pipeline ---------------------------------------------------------------------------------
def diagnose(train_flights, test_flights=None, prior="tilt-drag", targets=None, *,
             config: DiagnoseConfig | None = None, user_effects=None, progress=None) -> DiagnosisResult:
    """Diagnose ``prior`` on flights: build the datasets, then :func:`diagnose_datasets`.

    ``prior``: a PriorModel, a name (``file.toml:name`` for user priors) or ``"auto"``
    (:func:`priors.models.choose_prior` on the signals every training flight has at a usable rate). ``targets``
    None: the prior's targets among vx_dot, vy_dot, vz_dot.
    """
    cfg = (config or DiagnoseConfig()).validate()
    train_flights = list(train_flights)
    pr, label = choose_diagnose_prior(prior, train_flights, cfg.ts)
    if targets is None:
        targets = targets_for(pr)
    check_prior_data(train_flights, pr, targets, cfg.ts, "training")
    if test_flights:
        check_prior_data(test_flights, pr, targets, cfg.ts, "test")
    train = build_datasets(train_flights, targets, pr, cfg)
    test = build_datasets(test_flights, targets, pr, cfg) if test_flights else None
    return diagnose_datasets(train, test, prior=pr, prior_label=label, config=cfg,
                             user_effects=user_effects, progress=progress)


def choose_diagnose_prior(prior, flights, ts: float) -> tuple[object, str]:
    """(PriorModel, label for the report) from ``prior`` (a PriorModel, a name or ``"auto"``,
    which chooses among the signals every flight has at a usable rate for a grid of ``ts`` s,
    as identify does: :func:`droneid.fitness.usable_signals`)."""
    if not isinstance(prior, str):
        return resolve_prior(prior), getattr(prior, "name", type(prior).__name__)
    pr, why = prior_for(prior, usable_signals(flights, ts))
    if prior not in ("auto", "rotor-thrust"):
        return pr, prior
    args = ", ".join(f"{k}={pr.params[k]}" for k in ("source", "motors") if k in pr.params)
    return pr, f"{pr.name}" + (f" ({args})" if args else "") + f": {why}"


def build_datasets(flights, targets, prior, cfg: DiagnoseConfig) -> dict[str, Dataset]:
    """One Dataset per target on the configured grid (all other signals in ``extra``, plus the
    motor speeds ``rpm1..`` every flight has: the most direct thrust signal for the effects)."""
    flights = list(flights)
    builder = DatasetBuilder(ts=cfg.ts, method=cfg.method)
    rpm = [f"rpm{i}" for i in range(1, 17)
           if flights and all(f"rpm{i}" in getattr(fl, "signals", ()) for fl in flights)]
    out = {}
    for tgt in targets:
        inputs = tuple(prior.inputs(tgt)) if hasattr(prior, "inputs") else None
        ds = builder.build(flights, target=tgt, inputs=inputs)
        more = [n for n in rpm if n not in ds.columns()]
        if more:
            ds = builder.build(flights, target=tgt, inputs=inputs, extras=[*ds.extra, *more])
        out[tgt] = ds
    return out


def _select_effects(user_effects, only) -> dict:
    """The catalogue plus user effects, restricted to ``only`` (ids) when given."""
    effects = dict(CATALOGUE)
    for e in (user_effects.values() if isinstance(user_effects, Mapping) else user_effects or ()):
        effects[e.id] = e
    if only is not None:
        for eid in only:
            if eid not in effects:
                raise ConfigError(f"unknown effect '{eid}'{did_you_mean(eid, effects)}; known: {', '.join(effects)}")
        effects = {k: v for k, v in effects.items() if k in only}
    return effects


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


class _Model:
    """The stacked least-squares problem: base (prior) terms plus added effects, train and test.
    Coefficients, CV and constants come from training rows only; test rows are predicted."""

    def __init__(self, tr_parts, te_parts, terms, cfg, targets):
        self.tr_parts, self.te_parts, self.terms, self.cfg = tr_parts, te_parts, terms, cfg
        self.targets = targets
        self.tr = _Stack(tr_parts)
        self.te = _Stack(te_parts) if te_parts else None
        self.base = {name: {p.target: col} for p in tr_parts for name, col in p.base.items()}
        self.te_base = {name: {p.target: col} for p in te_parts or [] for name, col in p.base.items()}
        self._consts: dict = {}
        # weights 1/σ_t from the base refit (separable per target: the prior terms are per
        # target), so pooled CV errors are in units of each target's base residual
        r = self.tr.y - self.tr.design(self.base) @ _lstsq(self.tr.design(self.base), self.tr.y)
        sig = {i: max(rmse(r[self.tr.tidx == i], 0.0), 1e-12) for i in range(len(tr_parts))}
        self.tr.w = np.array([1.0 / sig[i] for i in self.tr.tidx])

    def constants(self, effect) -> dict:
        """{target: constants} of ``effect`` fixed from the training parts."""
        if effect.id not in self._consts:
            self._consts[effect.id] = {p.target: effect.constants(p.ctx) for p in self.tr_parts}
        return self._consts[effect.id]

    def effect_terms(self, effect) -> tuple[dict, dict]:
        """(train, test) terms of one effect, both with the training constants."""
        c = self.constants(effect)
        return (_terms_for(effect, self.tr_parts, c),
                _terms_for(effect, self.te_parts, c) if self.te_parts else {})

    def terms_of(self, effect_ids, effects) -> tuple[dict, dict]:
        """Train and test terms of the base model plus these effects (recomputed from the data)."""
        cur, cur_test = dict(self.base), dict(self.te_base)
        for eid in effect_ids:
            et, ett = self.effect_terms(effects[eid])
            cur.update(et)
            cur_test.update(ett)
        return cur, cur_test

    def fit(self, cur_terms, cur_test_terms) -> dict:
        """Fit on all training rows; blocked-CV predictions; test predictions (flight-specific
        parameters of the test flights by blocked CV on that flight). Test errors are None when
        the test flights lack a signal of a vehicle term (``test_note`` says which)."""
        tr, te, nb = self.tr, self.te, self.cfg.n_blocks
        X = tr.design(cur_terms)
        beta = _lstsq(X * tr.w[:, None], tr.y * tr.w)
        pred = X @ beta
        out = {"beta": dict(zip(cur_terms, beta.tolist())), "pred": pred, "train": tr.rmse_by_target(pred)}
        cvp, mse, n, folds = _cv(tr, X, nb)
        out.update(cv_pred=cvp, mse=mse, n=n, cv=tr.rmse_by_target(cvp), cv_resid=tr.w * (tr.y - cvp),
                   folds=[dict(zip(cur_terms, b.tolist())) for b in folds])
        out.update(test={t: None for t in self.targets}, test_all=None)
        if te is None:
            return out
        lacking = [k for k in cur_terms if "@" not in k
                   and set(cur_test_terms.get(k, {})) != set(cur_terms[k])]
        if lacking:
            out["test_note"] = ("the test flights lack signals of " + ", ".join(sorted(lacking))
                                + ": no test error")
            return out
        shared = [k for k in cur_terms if k in cur_test_terms]
        local = [k for k in cur_test_terms if k not in cur_terms]
        bsh = np.array([out["beta"][k] for k in shared])
        tp = te.design({k: cur_test_terms[k] for k in shared}) @ bsh if shared else np.zeros_like(te.y)
        if local:
            Xl = te.design({k: cur_test_terms[k] for k in local})
            r = te.y - tp
            lp = np.zeros_like(r)
            for k in range(nb):
                hold = te.block == k
                if hold.any():
                    lp[hold] = Xl[hold] @ _lstsq(Xl[~hold], r[~hold])
            out["test_local_beta"] = dict(zip(local, _lstsq(Xl, r).tolist()))
            tp = tp + lp
        out.update(test_pred=tp, test=te.rmse_by_target(tp),
                   test_all=math.sqrt(float(np.mean((te.y - tp) ** 2))))
        return out

    def base_info(self, fit) -> dict:
        """What effects read to interpret their coefficients: ``k_D`` {target: linear drag 1/s},
        ``jackknife``: the coefficients ({param: value}) of every leave-one-block-out fold, for
        block-jackknife uncertainties (rows within a block are correlated, folds are not)."""
        return {"k_D": {p.target: _k_drag(self.terms[p.target], p.target, p, fit["beta"])
                        for p in self.tr_parts}, "jackknife": fit.get("folds", [])}

    def evidence(self, cur, new, family_size: int, rank: int, what: str = "") -> dict:
        """The decision rule (:func:`droneid.decide.decide`) on the training blocks' held-out
        residuals (weighted, σ units), with the test errors attached for the report only."""
        cfg = self.cfg
        ev = evidence_of(decide(cur["cv_resid"], new["cv_resid"], self.tr.block, alpha=cfg.alpha,
                                family_size=family_size, rank=rank,
                                min_effect_pct=100 * cfg.min_rel_improvement, what=what))
        ev["cv_units"] = "pooled over targets, each in units of its base residual σ"
        return _with_test(ev, cur["test_all"], new["test_all"])


def _physical(effect, coef: Mapping[str, float], info) -> dict:
    """The effect's interpretation per flight (flight-specific effects) or once."""
    per = _split_flight_params(coef)
    its = {label: effect.interpret(c, info) for label, c in per.items()}
    text = "; ".join(it.text + (f" [{label}]" if label and len(its) > 1 else "") for label, it in its.items())
    return {"physical": text, "physical_values": next(iter(its.values())).values,
            "physical_per_flight": {label: it.values for label, it in its.items() if label}}


def _strip(coef: Mapping[str, float]) -> dict:
    return {k.split(".", 1)[1]: v for k, v in coef.items()}


def _fold(effect, model, beta) -> dict:
    """``foldable``, ``reason`` and ``features`` ({target: [{name, expr, coefficient}]}) of an
    added effect, the expressions with the training constants."""
    if not effect.foldable:
        return {"foldable": False, "reason": effect.fold_reason or "not written as expressions",
                "features": {}}
    feats = {}
    consts = model.constants(effect)
    for p in model.tr_parts:
        exprs = effect.expressions(p.ctx, consts.get(p.target))
        if exprs:
            feats[p.target] = [{"name": f"{effect.id}_{k}", "expr": e,
                                "coefficient": beta.get(f"{effect.id}.{k}", float("nan"))}
                               for k, e in exprs.items()]
    return {"foldable": True, "reason": "", "features": feats}


def _uses_derivative(expr_or_names) -> list[str]:
    names = ([s.name for s in expr_or_names.free_symbols] if isinstance(expr_or_names, sp.Basic)
             else list(expr_or_names))
    return sorted({n for n in names if is_measured_derivative(n)})


def _score(model, cur, cur_terms, cur_test, cands, family_size, rank):
    """[(effects, train terms, test terms, fit, evidence)] for candidate groups of effects, each
    judged by the one rule at Holm position ``rank`` of ``family_size``."""
    out = []
    for group in cands:
        et, ett = {}, {}
        for e in group:
            a, b = model.effect_terms(e)
            et.update(a)
            ett.update(b)
        new = model.fit({**cur_terms, **et}, {**cur_test, **ett})
        ev = model.evidence(cur, new, family_size, rank, "+".join(e.id for e in group))
        info = model.base_info(new)
        for e in group:
            # an effect that fits only with impossible values stands in for something else
            coef = {k: v for k, v in new["beta"].items() if k.startswith(e.id + ".")}
            why = e.implausible(_physical(e, coef, info)["physical_values"]) if coef else None
            if why:
                ev["implausible"] = True
                ev["reasons"].append(why)
                if ev["passed"]:
                    ev["passed"] = False
                    ev["text"] = ev["text"].replace(": accepted", f": rejected ({why})")
                else:
                    ev["text"] = ev["text"][:-1] + f"; {why})"
        out.append((group, et, ett, new, ev))
    return out


def _backward(model, effects, added, findings, steps, cur_terms, cur_test, cur, family):
    """Every added effect must still earn its place once the others are in: the same rule, the
    model without it against the full model, at the Holm threshold it was accepted at. An effect
    added greedily as a stand-in for one added after it (attitude bias for the part of anisotropic
    drag that rotates with yaw) then fails and is dropped (the worst first, then re-tested);
    its step keeps the evidence under ``dropped``. Effects judged on their own rows (per-motor
    thrust), effects that refine the others' inputs (wind's air velocity) and the members of a pair
    added jointly (they overlap by design: each alone is weaker with the other in) are kept."""
    while True:
        trials = []
        for eid in added:
            e = effects[eid]
            st = next(s for s in steps if s["effect"] == eid)
            if eid in findings or e.refine_fn is not None or len(added) < 2 or st.get("tested_jointly"):
                continue
            rank = int(st["evidence"].get("holm_rank", 1))
            terms, test_terms = model.terms_of([a for a in added if a != eid], effects)
            without = model.fit(terms, test_terms)
            ev = model.evidence(without, cur, family, min(rank, family), f"keep {eid} (all others in)")
            if not ev["passed"]:
                trials.append((ev["p_value"], eid, ev, terms, test_terms, without))
        if not trials:
            return cur_terms, cur_test, cur
        _, eid, ev, cur_terms, cur_test, cur = max(trials, key=lambda x: x[0])
        next(s for s in steps if s["effect"] == eid)["dropped"] = ev
        added.remove(eid)
        log.info("dropped %s: %s", eid, ev["text"])


def diagnose_datasets(train: Mapping[str, Dataset], test: Mapping[str, Dataset] | None = None, *,
                      prior="tilt-drag", config: DiagnoseConfig | None = None, user_effects=None,
                      progress: Callable | None = None, prior_label: str | None = None) -> DiagnosisResult:
    """Diagnose ``prior`` on per-target Datasets (see the module docstring).

    ``train``: {target: Dataset} of the training flights (they alone decide); ``test``: the same
    targets on test flights (reported only, never used for a choice); ``prior``: a PriorModel or
    a name. The result's ``final_effects[*]["features"]`` are ready to fold into the prior.
    """
    cfg = (config or DiagnoseConfig()).validate()
    if not train:
        raise DataError("no training datasets")
    pr = resolve_prior(prior)
    targets = list(train)
    if test is not None and set(test) != set(targets):
        raise DataError(f"test datasets cover {sorted(test)}, training datasets {sorted(targets)}")
    effects = _select_effects(user_effects, cfg.effects)
    if cfg.n_blocks is None:
        cfg = replace(cfg, n_blocks=diagnose_blocks(min(len(d) for d in train.values())))
    terms = {t: _prior_terms(pr, t) for t in targets}
    tr_parts = [_make_part(train[t], t, terms[t], cfg) for t in targets]
    for p in tr_parts:
        if p.y.size < 5 * cfg.n_blocks:
            raise DataError(f"{p.target}: only {p.y.size} training samples; need at least "
                            f"{5 * cfg.n_blocks} for {cfg.n_blocks}-block cross-validation")
    # G at the scale of the base refit on the training flights (effects read relative to it)
    base_beta = _Model(tr_parts, None, terms, cfg, targets).fit(
        {n: {p.target: c} for p in tr_parts for n, c in p.base.items()}, {})["beta"]
    terms = {t: terms[t].fitted(t, base_beta) for t in targets}
    tr_parts = [_make_part(train[t], t, terms[t], cfg) for t in targets]
    te_parts = [_make_part(test[t], t, terms[t], cfg, "test") for t in targets] if test is not None else None
    testable, untestable, not_applicable = _testability(effects, tr_parts, targets,
                                                        cfg.allow_measured_derivatives)
    model = _Model(tr_parts, te_parts, terms, cfg, targets)
    tr = model.tr

    cur_terms, cur_test = model.terms_of((), effects)
    cur = base_fit = model.fit(cur_terms, cur_test)
    steps, added, candidates_log, plot_steps = [], [], [], []
    total = cfg.max_steps + 1
    # the family of every candidate the diagnosis may try: each testable effect and each pair of
    # the pair_top best; the k-th step accepted is judged at Holm's alpha / (family − k + 1)
    # effects whose signals exist but whose preconditions fail may become testable once another
    # effect refines the inputs (the wind's air speed for quadratic drag): re-checked every step
    pending = [effects[eid] for eid in untestable
               if not any(effects[eid].missing(p.ctx.available()) for p in tr_parts
                          if effects[eid].applies_to(p.target))]
    n_top = min(cfg.pair_top, len(testable) + len(pending)) if cfg.pair_top >= 2 else 0
    family = max(1, len(testable) + len(pending) + n_top * (n_top - 1) // 2)
    findings = {}
    for e in testable:
        # effects judged on other rows than the v̇ residual (per-motor thrust: the thrust shares)
        if e.assess_fn is None:
            continue
        p = next(q for q in tr_parts if e.applies_to(q.target))
        e0, e1, rows, interp = e.assess(p.ctx, p.block)
        ev = _with_test(evidence_of(decide(e0, e1, rows, alpha=cfg.alpha, family_size=family,
                                           rank=min(len(added) + 1, family),
                                           min_effect_pct=100 * cfg.min_rel_improvement, what=e.id)),
                        None, None)
        candidates_log.append({"step": 0, "assessed": e.id, "scores": [
            {"effect": e.id, **{k: ev[k] for k in ("cv_rmse_after", "rel_improvement", "statistic",
                                                   "p_value", "p_threshold", "blocks_improved",
                                                   "test_rmse_after", "passed", "reasons", "text")}}]})
        if not ev["passed"] or len(added) >= cfg.max_steps:
            continue
        findings[e.id] = interp
        ev["indistinguishable_from"] = []
        steps.append({"effect": e.id, "description": e.description, "coefficients": {},
                      "physical": interp.text, "physical_values": interp.values,
                      "physical_per_flight": {}, "per_flight": False, "tested_jointly": None,
                      "rmse": {t: {"train": cur["train"][t], "test": cur["test"][t], "cv": cur["cv"][t]}
                               for t in targets},
                      "test_note": cur.get("test_note"), "evidence": ev})
        et, ett = model.effect_terms(e)
        new = model.fit({**cur_terms, **et}, {**cur_test, **ett})
        plot_steps.append({q.target: {"effect": e.id, "residual": q.y - cur["pred"][tr.tidx == i],
                                      "contrib": sum(new["beta"][k] * et[k][q.target] for k in et
                                                     if q.target in et[k])}
                           for i, q in enumerate(tr_parts)})
        steps[-1]["rmse"] = {t: {"train": new["train"][t], "test": new["test"][t], "cv": new["cv"][t]}
                             for t in targets}
        steps[-1]["coefficients"] = _strip({k: new["beta"][k] for k in et})
        cur_terms, cur_test, cur = {**cur_terms, **et}, {**cur_test, **ett}, new
        added.append(e.id)
    n_assessed = len(added)
    for step in range(cfg.max_steps - n_assessed):
        rank = min(len(added) + 1, family)
        for e in list(pending):
            if not any(e.untestable_data(p.ctx) for p in tr_parts if e.applies_to(p.target)):
                pending.remove(e)
                testable.append(e)
                untestable.pop(e.id, None)
        if progress:
            progress(step, total, "scoring effects")
        singles = []
        for e in testable:
            if e.id in added or e.assess_fn is not None:   # assessed once, on their own rows
                continue
            et = model.effect_terms(e)[0]
            if not et or all(np.allclose(c, 0) for cols in et.values() for c in cols.values()):
                continue
            singles.append(e)
        if not singles:
            break
        scores = _score(model, cur, cur_terms, cur_test, [(e,) for e in singles], family, rank)
        # best first by held-out error; a candidate that only fits with impossible values goes last
        # (it stands in for something else: the next one is judged instead)
        scores.sort(key=lambda s: (bool(s[4].get("implausible")), s[4]["cv_rmse_after"]))
        log_entry = {"step": step + 1, "scores": [
            {"effect": "+".join(e.id for e in g), **{k: ev[k] for k in (
                "cv_rmse_after", "rel_improvement", "statistic", "p_value", "p_threshold",
                "blocks_improved", "test_rmse_after", "passed", "reasons", "text")}}
            for g, _, _, _, ev in scores]}
        candidates_log.append(log_entry)
        best = scores[0]
        jointly = False
        if not best[4]["passed"] and best[4]["rel_improvement"] >= cfg.pair_min_gain and cfg.pair_top >= 2:
            # overlapping effects: test the best pairs jointly, Bonferroni over singles + pairs
            top = [g[0] for g, *_ in scores[:cfg.pair_top]]
            pairs = [(a, b) for i, a in enumerate(top) for b in top[i + 1:]]
            single_cv = {g[0].id: ev["cv_rmse_after"] for g, _, _, _, ev in scores}
            pscores = _score(model, cur, cur_terms, cur_test, pairs, family, rank)
            for g, _, _, _, ev in pscores:
                worst_single = min(single_cv[e.id] for e in g)
                ev["beats_members"] = ev["cv_rmse_after"] <= (1 - cfg.min_rel_improvement) * worst_single
                if ev["passed"] and not ev["beats_members"]:
                    ev["passed"] = False
                    ev["reasons"].append("the pair does not beat each of its effects alone by "
                                         f"{100 * cfg.min_rel_improvement:.2f} %")
                    ev["text"] = ev["text"].replace(": accepted", ": rejected (" + ev["reasons"][-1] + ")")
            pscores.sort(key=lambda s: (bool(s[4].get("implausible")), s[4]["cv_rmse_after"]))
            log_entry["pairs"] = [{"effects": [e.id for e in g], **{k: ev[k] for k in (
                "cv_rmse_after", "rel_improvement", "statistic", "p_value", "p_threshold",
                "blocks_improved", "passed", "reasons", "text")}} for g, _, _, _, ev in pscores]
            log_entry["pairs_reason"] = (
                f"best single {best[0][0].id} gains {100 * best[4]['rel_improvement']:.1f} % but "
                f"fails ({'; '.join(best[4]['reasons'])}): pairs of the {len(top)} best tested jointly")
            if pscores and pscores[0][4]["passed"]:
                best, jointly = pscores[0], True
        group, et, ett, new, ev = best
        if not ev["passed"]:
            log.info("step %d: best candidate %s rejected: %s", step + 1,
                     "+".join(e.id for e in group), "; ".join(ev["reasons"]))
            break
        if not jointly:
            # candidates nearly as good (and significant) that the data cannot tell apart
            ev["indistinguishable_from"] = [g[0].id for g, _, _, _, v in scores[1:] if v["passed"]
                                            and v["rel_improvement"] >= 0.9 * ev["rel_improvement"]]
        else:
            ev["indistinguishable_from"] = []
        coef = {k: new["beta"][k] for k in et}
        local = {k: v for k, v in new.get("test_local_beta", {}).items() if k in ett}
        info = model.base_info(new)
        for e in group:
            ce = {k: v for k, v in {**coef, **local}.items() if k.startswith(e.id + ".")}
            steps.append({"effect": e.id, "description": e.description,
                          "coefficients": _strip({k: v for k, v in coef.items() if k.startswith(e.id + ".")}),
                          **_physical(e, ce, info), "per_flight": e.per_flight,
                          "tested_jointly": [x.id for x in group] if jointly else None,
                          "rmse": {t: {"train": new["train"][t], "test": new["test"][t], "cv": new["cv"][t]}
                                   for t in targets},
                          "test_note": new.get("test_note"),
                          "evidence": ev})
        plot = {p.target: {"effect": "+".join(e.id for e in group),
                           "residual": p.y - cur["pred"][tr.tidx == i],
                           "contrib": sum(new["beta"][k] * et[k][p.target] for k in et if p.target in et[k])}
                for i, p in enumerate(tr_parts)}
        plot_steps.extend(plot for _ in group)      # one entry per step (a pair: the joint term)
        added.extend(e.id for e in group)
        cur_terms, cur_test, cur = {**cur_terms, **et}, {**cur_test, **ett}, new
        refiners = [effects[eid] for eid in added if effects[eid].refine_fn is not None]
        if refiners:
            # an effect may refine itself after a fit (e.g. the wind sets the air velocity v − w
            # that drag acts on): refresh the contexts and refit, twice (a fixed point)
            for _ in range(2):
                _refine(refiners, tr_parts, te_parts, cur, model.base_info(cur))
                cur_terms, cur_test = model.terms_of(added, effects)
                cur = model.fit(cur_terms, cur_test)
        if len(added) >= cfg.max_steps:
            break
    cur_terms, cur_test, cur = _backward(model, effects, added, findings, steps, cur_terms, cur_test,
                                         cur, family)
    if progress:
        progress(cfg.max_steps, total, "open-ended search")
    open_ended = _open_ended_all(model, cur, cfg)

    info = model.base_info(cur)
    final_effects, notes = [], []
    for where, sets in (("training", train), ("test", test or {})):
        counts: dict[str, int] = {}
        for d in sets.values():   # each target's dataset counts the signals it uses
            for name, c in d.screened.items():
                counts[name] = max(counts.get(name, 0), c)
        if counts:
            notes.append(f"screened ({where}): " + ", ".join(f"{n} {c}" for n, c in counts.items())
                         + " implausible sample(s) or jump(s) left out before any fit (docs/estimates.md)")
    for eid in added:
        if eid in findings:
            final_effects.append({"effect": eid, "physical": findings[eid].text,
                                  "physical_values": findings[eid].values, "physical_per_flight": {},
                                  "coefficients": _strip({k: v for k, v in cur["beta"].items()
                                                          if k.startswith(eid + ".")}),
                                  **_fold(effects[eid], model, cur["beta"])})
            continue
        coef = {k: v for k, v in {**cur["beta"], **cur.get("test_local_beta", {})}.items()
                if k.startswith(eid + ".")}
        train_coef = {k: v for k, v in cur["beta"].items() if k.startswith(eid + ".")}
        final_effects.append({"effect": eid, **_physical(effects[eid], coef, info),
                              "coefficients": _strip(train_coef), **_fold(effects[eid], model, cur["beta"])})
    derivs = sorted({n for fe in final_effects for fs in fe["features"].values() for f in fs
                     for n in _uses_derivative(f["expr"])}
                    | {n for eid in added for n in _uses_derivative(_needs_signals(effects[eid]))}
                    | {n for o in open_ended.values() if o and o.get("passed")
                       for n in _uses_derivative(_equation_names(o))})
    if derivs:
        notes.append(f"the model uses {', '.join(derivs)}, a measured derivative of the output: "
                     "it cannot be simulated or used by a controller")
    not_detected = [e.id for e in testable if e.id not in added]
    conclusion = NO_FURTHER
    if added:
        conclusion = (f"added {', '.join(added)}; {NO_FURTHER}" if len(added) < cfg.max_steps
                      else f"added {', '.join(added)} (step limit {cfg.max_steps} reached)")
    if any(o and o.get("passed") for o in open_ended.values()):
        conclusion += "; the open-ended search found an unnamed term (see open_ended)"
    if derivs:
        conclusion += f" (NOT simulable: uses the measured derivative {', '.join(derivs)})"
    sources = {"train": sorted({s for d in train.values() for s in d.sources}),
               "test": sorted({s for d in test.values() for s in d.sources}) if test else []}
    label = prior_label or (prior if isinstance(prior, str) else getattr(pr, "name", type(pr).__name__))
    return DiagnosisResult(
        targets=_target_summaries(model, base_fit, cur, cur_terms, steps, open_ended),
        steps=steps, effects_added=added, untestable=untestable, not_detected=not_detected,
        conclusion=conclusion, open_ended=open_ended, config=asdict(cfg),
        prior=label, sources=sources, candidates=candidates_log, final_effects=final_effects,
        not_applicable=not_applicable, simulable=not derivs, notes=notes,
        series=_series(model, base_fit, cur, plot_steps))


def _equation_names(o: dict) -> list[str]:
    """The offered signals that the open-ended equation actually uses."""
    words = set(re.findall(r"[A-Za-z_][A-Za-z_0-9]*", str(o.get("equation", ""))))
    return [n for n in o.get("signals", ()) if n in words]


def fold_into_prior(result: DiagnosisResult, prior):
    """A new :class:`priors.models.PriorModel`: ``prior`` plus every foldable final effect's
    features (each ``coefficient · expr``, role ``"other"``, description naming the effect), with
    the signals they use added to the prior's inputs. Effects that are not foldable (per-flight
    conditions, attitude delay, measured derivatives) are left out. Raises ConfigError when the
    prior is not a PriorModel."""
    if not isinstance(prior, PriorModel):
        raise ConfigError(f"fold_into_prior needs a PriorModel, got {type(prior).__name__}")
    terms = {t: list(prior.features(t)) for t in prior.targets}
    inputs = {t: list(prior.inputs(t)) for t in prior.targets}
    for fe in result.final_effects:
        if not fe.get("foldable"):
            continue
        for t, feats in fe["features"].items():
            if t not in terms:
                continue
            for f in feats:
                expr = sp.Float(f["coefficient"]) * f["expr"]
                terms[t].append(PriorFeature(f["name"], expr, f"diagnosed effect {fe['effect']}: "
                                             f"{fe['physical']}", "other"))
                inputs[t].extend(sorted(s.name for s in expr.free_symbols if s.name not in inputs[t]))
    added = [fe["effect"] for fe in result.final_effects if fe.get("foldable")]
    if not added:
        return prior
    return PriorModel(f"{prior.name}+{'+'.join(added)}",
                      f"{prior.description} Plus the diagnosed effects {', '.join(added)}.",
                      terms, inputs, dict(prior.params), vehicle=prior.vehicle,
                      constraints=prior.constraints, intercept=dict(prior.intercept))


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
            "linear_drag_k_D": _k_drag(tp, t, p, base_fit["beta"]),
            "linear_drag_k_D_after": _k_drag(tp, t, p, cur["beta"]),
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


# -- open-ended search ----------------------------------------------------------------------------
def _open_ended_all(model, cur, cfg) -> dict:
    parts = model.tr_parts
    if cfg.generations <= 0:
        return {p.target: {"ran": False, "reason": "disabled (generations = 0)"} for p in parts}
    out = {}
    for i, p in enumerate(parts):
        test = None
        if model.te_parts and "test_pred" in cur:
            q = model.te_parts[i]
            test = (q, q.y - cur["test_pred"][model.te.tidx == i])
        out[p.target] = _open_ended(p, p.y - cur["pred"][model.tr.tidx == i], test, cfg, len(parts))
    return out


def _clock_like(v: np.ndarray, t: np.ndarray, flight: np.ndarray, limit: float = 0.9) -> bool:
    """True for a signal that drifts monotonically with time in some flight (|Spearman ρ| with
    t above ``limit``, e.g. a sagging battery voltage): it acts as a clock, and a search given a
    clock can fit any slow drift of the residual and carry it across interleaved blocks."""
    from scipy.stats import spearmanr
    for f in np.unique(flight):
        m = flight == f
        if m.sum() > 10 and np.ptp(v[m]) > 0:
            rho = spearmanr(v[m], t[m]).statistic
            if np.isfinite(rho) and abs(rho) > limit:
                return True
    return False


def _signal_matrix(part, names):
    return np.column_stack([part.ctx.columns[n] for n in names])


def _open_ended(part: _Part, resid: np.ndarray, test, cfg: DiagnoseConfig, family: int = 1) -> dict:
    """SNGP on one target's remaining residual; its term is judged by the one rule
    (:func:`droneid.decide.decide`, interleaved-block 2-fold CV, Bonferroni over ``family``
    targets)."""
    names = sorted(n for n, v in part.ctx.columns.items()
                   if n not in _OPEN_EXCLUDE and np.ptp(v) > 0 and n.isidentifier()
                   and not _clock_like(v, part.t, part.flight))
    if not names:
        return {"ran": False, "reason": "no signals"}
    X = _signal_matrix(part, names)

    def run(rows, seed):
        idx = np.flatnonzero(rows)
        if idx.size > cfg.max_samples:
            idx = idx[np.linspace(0, idx.size - 1, cfg.max_samples).astype(int)]
        m = SNGPRegressor(population_size=cfg.population_size, generations=cfg.generations,
                          n_features=cfg.n_features, max_depth=cfg.max_depth,
                          n_threads=1, seed=seed)
        m.fit(X[idx], resid[idx], feature_names=names)
        return m

    # interleaved-block 2-fold CV: fit on even blocks, predict odd, and vice versa
    even = part.block % 2 == 0
    pred = np.zeros_like(resid)
    for k, rows in enumerate((even, ~even)):
        m = run(rows, cfg.seed + k)
        pred[~rows] = np.asarray(m.predict(X[~rows]), float)
    pred[~np.isfinite(pred)] = 0.0
    final = run(np.ones(resid.size, bool), cfg.seed + 7)
    tb = ta = None
    if test is not None and all(nm in test[0].ctx.columns for nm in names):
        # reported only: the test flights never decide
        q, tres = test
        tp = np.asarray(final.predict(_signal_matrix(q, names)), float)
        tp[~np.isfinite(tp)] = 0.0
        tb = rmse(tres, 0.0)
        ta = rmse(tres, tp)
    ev = _with_test(evidence_of(decide(resid, resid - pred, part.block, alpha=cfg.alpha,
                                       family_size=family, min_effect_pct=100 * cfg.min_rel_improvement,
                                       what=f"open-ended term for {part.target}")), tb, ta)
    return {"ran": True, "signals": names, "equation": str(getattr(final, "equation_", final.expr_)),
            "rmse_train_residual": float(getattr(final, "rmse_train_", float("nan"))),
            "generations": cfg.generations, "passed": ev["passed"], "evidence": ev}
