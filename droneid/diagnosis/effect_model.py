"""Effects as columns of one stacked least-squares problem, judged by the one decision rule.

The diagnosis (:mod:`droneid.diagnosis.diagnose`) works on this model: the prior's terms per target
(:func:`prior_terms`, G and the linear drag read from the terms' roles), one :class:`Part` per
target and role (train or test) with its :class:`priors.effects.EffectContext`, and
:class:`EffectModel`, which stacks the targets, fits the prior plus any set of effects on the
TRAINING rows (weighted least squares, weights 1/σ of each target's base residual), predicts
held-out blocks (leave-one-block-out) and applies :func:`droneid.fitting.decide.decide` to the held-out
residuals with and without a candidate (:meth:`EffectModel.evidence`).
:func:`score_candidates` judges candidate groups of effects (and rejects those that fit only with
impossible values); :func:`drop_stand_ins` re-judges every added effect with the others in.
Test rows are predicted, never fitted (flight-specific parameters of a test flight by blocked CV
on that flight) and never take part in a decision.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import sympy as sp

from priors.effects import EffectContext, is_measured_derivative

from droneid.dataset.data import Dataset
from droneid.fitting.decide import decide
from droneid.diagnosis.result import DiagnoseConfig, evidence_of, with_test_errors
from droneid.errors import ConfigError, MissingSignalError
from droneid.core.expressions import compile_expression, symbol
from droneid.dataset.validation import block_ids, block_in_flight
from droneid.core.numerics import lstsq, rmse
from droneid.core.targets import HORIZONTAL, velocity_of

log = logging.getLogger(__name__)

__all__ = ["PriorTerms", "prior_terms", "Part", "make_part", "EffectModel", "diagnose_blocks",
           "refine_contexts", "air_jacobians", "linear_drag_of", "physical_terms", "strip_effect_id", "fold_features",
           "uses_derivative", "score_candidates", "drop_stand_ins"]

_ANGLES = ("roll", "pitch")


_G_ROLES = ("tilt", "thrust")


@dataclass(frozen=True)
class PriorTerms:
    """One target's prior terms; ``tilt`` = G (sum of role tilt/thrust terms), ``tilt_role``;
    ``drag`` = names of the linear-drag terms; ``velocity`` = the target's velocity signal."""
    names: tuple[str, ...]
    exprs: tuple[sp.Expr, ...]
    tilt: sp.Expr | None
    velocity: str | None
    tilt_role: str = "tilt"
    drag: tuple[str, ...] = ()
    g_parts: tuple[tuple[str, sp.Expr], ...] = ()

    def fitted(self, target: str, beta: Mapping[str, float]) -> "PriorTerms":
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


def prior_terms(prior, target: str) -> PriorTerms:
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
    return PriorTerms(names, exprs, sp.Add(*[e for _, e in g_parts]) if g_parts else None,
                       vel if drag else None, role, drag, tuple(g_parts))


@dataclass
class Part:
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


def make_part(ds: Dataset, target: str, terms: PriorTerms, cfg: DiagnoseConfig, role: str = "train"):
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
        return make_part(ds.subset(good), target, terms, cfg, role)
    prior_sum = np.sum(list(base.values()), axis=0)
    blocks = block_ids(ds.t, ds.flight, cfg.n_blocks)
    return Part(target, ctx, ds.y, ds.t, ds.flight, blocks, base, prior_sum, role, tuple(ds.sources))


class _Stack:
    """Rows of several targets stacked; terms are {param: {target: column}}. ``w``: row weights
    of the least squares and of the CV errors (1/σ of each target's base residual, so a noisy
    target such as v̇z does not dictate a coefficient shared with v̇x, v̇y)."""

    def __init__(self, parts: Sequence[Part]):
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
    block, 16 to 30 blocks. More blocks than :func:`droneid.dataset.validation.n_blocks_for` because every
    diagnosis decision is a sign-flip test over blocks at a family-wise threshold (α/13 and
    below, 7.7e-4 at α = 0.01): its p is at least 2^−B (2.4e-4 with 12 blocks, which then must
    ALL improve; 1.5e-5 with 16, which leaves room for a block or two that does not)."""
    return int(np.clip(n // 60, 16, 30))


def _lstsq(X, y):
    return lstsq(X, y, rcond=1e-10)


def _cv(stack: _Stack, X: np.ndarray, n_blocks: int):
    """Held-out predictions by leave-one-block-out (weighted least squares): fold k holds out
    time block k of every flight (:func:`~droneid.dataset.validation.block_in_flight`), so a CV costs
    ``n_blocks`` solves however many flights; the decisions then take every (flight, block) as
    its own unit. Per-fold weighted MSE and sample counts; the coefficients of every fold (rows;
    for block-jackknife errors)."""
    pred = np.zeros_like(stack.y)
    w = stack.w
    fold = block_in_flight(stack.block, n_blocks)
    folds = []
    for k in range(n_blocks):
        test = fold == k
        if not test.any():
            continue
        beta = _lstsq(X[~test] * w[~test, None], stack.y[~test] * w[~test])
        folds.append(beta)
        pred[test] = X[test] @ beta
    r2 = (w * (stack.y - pred)) ** 2
    mse = np.array([np.mean(r2[fold == k]) if np.any(fold == k) else 0.0 for k in range(n_blocks)])
    n = np.array([np.sum(fold == k) for k in range(n_blocks)])
    return pred, mse, n, np.array(folds)


def _terms_for(effect, parts: Sequence[Part], consts: Mapping[str, dict] | None = None) -> dict:
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


def refine_contexts(refiners, tr_parts, te_parts, fit, base, jacobians=None) -> None:
    """Let each added effect with a refine hook (:meth:`priors.effects.Effect.refine`) update every
    part's context from ``fit``: its coefficients per flight (test flights: their own per-flight
    estimates, else the training ones) and ``base`` (``k_D`` in 1/s). E.g. the wind sets the air
    velocity that drag effects act on. ``jacobians``: :func:`air_jacobians` of the same fit, given
    to the hooks as ``base["air_jacobian"]`` ({flight code: 2×2}) of the parts' own flights."""
    for kind, parts, betas in (("train", tr_parts, fit["beta"]),
                               ("test", te_parts or [], {**fit["beta"], **fit.get("test_local_beta", {})})):
        if jacobians is not None:
            base = {**base, "air_jacobian": jacobians.get(kind, {})}
        for e in refiners:
            own = _split_flight_params({k: v for k, v in betas.items() if k.startswith(e.id + ".")})
            shared = own.get(None, {})
            for p in parts:
                coef = {int(f): {**shared, **own.get(p.flight_label(int(f)), {})}
                        for f in np.unique(p.flight)}
                cols = e.refine(p.ctx, coef, base)
                if cols:
                    p.ctx = p.ctx.with_columns(cols)


#: the wind step of :func:`air_jacobians`' central differences (m/s)
_AIR_STEP_M_S = 0.01


def air_jacobians(model, effects, added, fit) -> dict:
    """How the model's air-velocity terms move with the wind estimate, per flight: {"train" |
    "test": {flight code: 2×2 array}}, row i the mean of v̇x (i = 0) or v̇y (i = 1) over the
    flight's rows, column j the derivative with respect to ŵ_x (j = 0) or ŵ_y (j = 1), in 1/s.

    Central differences of ±:data:`_AIR_STEP_M_S` on the wind estimate of every flight at once
    (the flights' rows are disjoint), through every added effect's terms with the fitted
    coefficients: the quadratic drag's c(|u|I + u uᵀ/|u|) and the anisotropic drag's body-axis
    matrix, u = v − ŵ, whatever effects read the air velocity. The wind's hook needs them: its
    offset measures K·w + A·(w − ŵ) (K the linear drag, A this matrix), not K·w, once a drag effect
    acts on v − ŵ, so ŵ = offset / K alone is a fixed point that diverges when A outweighs K (a
    quadratic drag of 0.16 1/m at 2 m/s airspeed against a linear drag of 0.35 1/s)."""
    out: dict = {}
    readers = [effects[eid] for eid in added if effects[eid].refine_fn is None]
    consts = {e.id: model.constants(e) for e in readers}
    for kind, parts, beta in (("train", model.tr_parts, fit["beta"]),
                              ("test", model.te_parts or [], {**fit["beta"], **fit.get("test_local_beta", {})})):
        rows = [(i, p) for p in parts for i, tgt in enumerate(HORIZONTAL) if p.target == tgt]
        if not rows or not readers:
            continue
        saved = [p.ctx for p in parts]
        deriv = {}
        try:
            for j in range(2):
                sides = []
                for sign in (1.0, -1.0):
                    for p, ctx in zip(parts, saved):
                        c = ctx.columns
                        if "vx" not in c or "vy" not in c:
                            continue
                        wx = c["vx"] - c.get("vx_air", c["vx"]) + (sign * _AIR_STEP_M_S if j == 0 else 0.0)
                        wy = c["vy"] - c.get("vy_air", c["vy"]) + (sign * _AIR_STEP_M_S if j == 1 else 0.0)
                        ax, ay = c["vx"] - wx, c["vy"] - wy
                        p.ctx = ctx.with_columns({"vx_air": ax, "vy_air": ay, "speed_air": np.hypot(ax, ay)})
                    pred = {}
                    for e in readers:
                        for name, cols in _terms_for(e, parts, consts[e.id]).items():
                            for tgt, col in cols.items():
                                pred[tgt] = pred.get(tgt, 0.0) + beta.get(name, 0.0) * col
                    sides.append(pred)
                    for p, ctx in zip(parts, saved):
                        p.ctx = ctx
                for i, p in rows:
                    d = (np.asarray(sides[0].get(p.target, 0.0)) - np.asarray(sides[1].get(p.target, 0.0))) \
                        / (2 * _AIR_STEP_M_S)
                    d = np.broadcast_to(d, p.flight.shape)
                    for f in np.unique(p.flight):
                        deriv.setdefault(int(f), np.zeros((2, 2)))[i, j] = float(np.mean(d[p.flight == f]))
        finally:
            for p, ctx in zip(parts, saved):
                p.ctx = ctx
        out[kind] = deriv
    return out


def _split_flight_params(coef: Mapping[str, float]) -> dict[str | None, dict]:
    """{flight label or None: {param: value}} from (possibly flight-specific) coefficients."""
    out: dict = {}
    for k, v in coef.items():
        name, _, label = k.partition("@")
        out.setdefault(label or None, {})[name.split(".", 1)[-1]] = v
    return out


def linear_drag_of(terms: PriorTerms, target, part: Part, coef: Mapping[str, float]) -> float | None:
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


class EffectModel:
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
            te_fold = block_in_flight(te.block, nb)
            for k in range(nb):
                hold = te_fold == k
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
        return {"k_D": {p.target: linear_drag_of(self.terms[p.target], p.target, p, fit["beta"])
                        for p in self.tr_parts}, "jackknife": fit.get("folds", [])}

    def evidence(self, cur, new, family_size: int, rank: int, what: str = "") -> dict:
        """The decision rule (:func:`droneid.fitting.decide.decide`) on the training blocks' held-out
        residuals (weighted, σ units), with the test errors attached for the report only."""
        cfg = self.cfg
        ev = evidence_of(decide(cur["cv_resid"], new["cv_resid"], self.tr.block, alpha=cfg.alpha,
                                family_size=family_size, rank=rank,
                                min_effect_pct=100 * cfg.min_rel_improvement, what=what))
        ev["cv_units"] = "pooled over targets, each in units of its base residual σ"
        return with_test_errors(ev, cur["test_all"], new["test_all"])


def physical_terms(effect, coef: Mapping[str, float], info) -> dict:
    """The effect's interpretation per flight (flight-specific effects) or once."""
    per = _split_flight_params(coef)
    its = {label: effect.interpret(c, info) for label, c in per.items()}
    text = "; ".join(it.text + (f" [{label}]" if label and len(its) > 1 else "") for label, it in its.items())
    return {"physical": text, "physical_values": next(iter(its.values())).values,
            "physical_per_flight": {label: it.values for label, it in its.items() if label}}


def strip_effect_id(coef: Mapping[str, float]) -> dict:
    return {k.split(".", 1)[1]: v for k, v in coef.items()}


def fold_features(effect, model, beta) -> dict:
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


def uses_derivative(expr_or_names) -> list[str]:
    names = ([s.name for s in expr_or_names.free_symbols] if isinstance(expr_or_names, sp.Basic)
             else list(expr_or_names))
    return sorted({n for n in names if is_measured_derivative(n)})


def score_candidates(model, cur, cur_terms, cur_test, cands, family_size, rank):
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
            why = e.implausible(physical_terms(e, coef, info)["physical_values"]) if coef else None
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


def drop_stand_ins(model, effects, added, findings, steps, cur_terms, cur_test, cur, family):
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

