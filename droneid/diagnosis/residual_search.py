"""The open-ended fallback of the diagnosis: an SNGP search on what the catalogue leaves.

:func:`search_residuals` runs, per target, an SNGP search on the remaining training residual over
the causal signals (no absolute position, no clock-like signal: :func:`clock_like`), judged by the
one decision rule (:func:`droneid.fitting.decide.decide`) on interleaved-block 2-fold CV, Bonferroni over
the targets. Its term is a finding only when it passes and no addend of its equation is refused by
the physics guard (:mod:`droneid.fitting.physics_guard`: one motor alone, absolute position, mixed units);
test errors are reported, never used.
"""
from __future__ import annotations

import re

import numpy as np
import sympy as sp

from droneid.fitting.decide import decide
from droneid.diagnosis.result import DiagnoseConfig, evidence_of, with_test_errors
from droneid.diagnosis.effect_model import Part
from droneid.core.numerics import rmse
from droneid.fitting.physics_guard import POSITION_SIGNALS, guard_terms
from droneid.sngp import SNGPRegressor
from droneid.dataset.validation import block_in_flight

__all__ = ["search_residuals", "clock_like", "equation_signals", "physics_refusal"]

_OPEN_EXCLUDE = POSITION_SIGNALS | {"qw", "qx", "qy", "qz", "v_axis", "t"}


def equation_signals(o: dict) -> list[str]:
    """The offered signals that the open-ended equation actually uses."""
    words = set(re.findall(r"[A-Za-z_][A-Za-z_0-9]*", str(o.get("equation", ""))))
    return [n for n in o.get("signals", ()) if n in words]


def search_residuals(model, cur, cfg, *, per_motor: bool = False, height: bool = False) -> dict:
    """{target: what the open-ended search found on its remaining training residual}. A term is
    a finding only when it passes the one rule AND the physics guard
    (:func:`droneid.fitting.physics_guard.guard_terms` on its terms; ``per_motor``: the per-motor thrust effect was
    found, ``height``: ground effect was testable on these flights)."""
    parts = model.tr_parts
    if cfg.generations <= 0:
        return {p.target: {"ran": False, "reason": "disabled (generations = 0)"} for p in parts}
    out = {}
    for i, p in enumerate(parts):
        test = None
        if model.te_parts and "test_pred" in cur:
            q = model.te_parts[i]
            test = (q, q.y - cur["test_pred"][model.te.tidx == i])
        out[p.target] = _search_one(p, p.y - cur["pred"][model.tr.tidx == i], test, cfg, len(parts),
                                    {"per_motor": per_motor, "height": height})
    return out


def clock_like(v: np.ndarray, t: np.ndarray, flight: np.ndarray, limit: float = 0.9) -> bool:
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


def physics_refusal(terms, signals, **kw) -> str | None:
    """Why the open-ended model cannot be a finding about the vehicle (its first term that
    :func:`droneid.fitting.physics_guard.guard_terms` refuses, named), or None.

    ``terms``: the SNGP model's own terms (``SymbolicModel.terms``, each one evolved feature as
    the engine evaluated it), the units identify's ladder guards (:func:`droneid.identify.ladder.final_rung`),
    never the expanded sum: expanding ``vx·(vx + z)`` into ``vx² + vx·z`` would hide that it adds a
    velocity to a height. A sympy expression is taken as one term per addend."""
    if isinstance(terms, sp.Basic):
        terms = sp.Add.make_args(terms)
    terms = [t for t in terms if not sp.sympify(t).is_Number]
    _, refused = guard_terms(terms, [sp.sstr(t) for t in terms], signals, **kw)
    if not refused:
        return None
    label, why = refused[0].removeprefix("dropped ").split(": ", 1)
    return f"physics guard: its term {label} is refused: {why}"


def _signal_matrix(part, names):
    return np.column_stack([part.ctx.columns[n] for n in names])


def _search_one(part: Part, resid: np.ndarray, test, cfg: DiagnoseConfig, family: int = 1,
                physics: dict | None = None) -> dict:
    """SNGP on one target's remaining residual; its term is judged by the one rule
    (:func:`droneid.fitting.decide.decide`, interleaved-block 2-fold CV, Bonferroni over ``family``
    targets)."""
    names = sorted(n for n, v in part.ctx.columns.items()
                   if n not in _OPEN_EXCLUDE and np.ptp(v) > 0 and n.isidentifier()
                   and not clock_like(v, part.t, part.flight))
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

    # interleaved-block 2-fold CV: fit on the even time blocks of every flight, predict the odd
    # ones, and vice versa
    even = block_in_flight(part.block, cfg.n_blocks) % 2 == 0
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
    ev = with_test_errors(evidence_of(decide(resid, resid - pred, part.block, alpha=cfg.alpha,
                                       family_size=family, min_effect_pct=100 * cfg.min_rel_improvement,
                                       what=f"open-ended term for {part.target}")), tb, ta)
    refused = physics_refusal(final.model_.terms, names, **(physics or {}))
    if refused:
        ev = {**ev, "passed": False, "reasons": [*ev["reasons"], refused], "text": f"{ev['text']}; {refused}"}
    return {"ran": True, "signals": names, "equation": str(getattr(final, "equation_", final.expr_)),
            "rmse_train_residual": float(getattr(final, "rmse_train_", float("nan"))),
            "generations": cfg.generations, "passed": ev["passed"], "evidence": ev}

