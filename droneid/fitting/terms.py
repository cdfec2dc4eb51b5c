"""Models as sums of terms, and the checks a term must pass: the building blocks of the ladder
(:mod:`droneid.identify.ladder`).

Every decision here uses TRAINING data only: blocked cross-validation over contiguous time
blocks of the training flights (:func:`droneid.core.regression.blocked_cv`, blocks from
:mod:`droneid.dataset.validation`). Test flights are evaluated for the report and never looked at.

- :class:`TermModel`: ``y = b0 + Σ b_i · term_i`` with sympy terms over canonical signals;
  :meth:`TermModel.fit` is least squares, :meth:`TermModel.cv_rmse` its blocked-CV error.
- :func:`trim_terms`: merge near-duplicate columns (cancelling pairs) and drop evolved terms that
  do not improve the CV error by ``margin``.
- :func:`plausible`: the model on a grid spanning the training inputs' ranges plus a margin
  stays within physical bounds (no blow-up outside the data).

Errors are in the target's units (m/s² for v̇).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import sympy as sp

from droneid.core.expressions import evaluate_expr
from droneid.core.numerics import rmse
from droneid.fitting.constancy import MIN_UNIT_ROWS, Constancy, constancies, unit_bounds, unit_estimate, units_of
from droneid.core.regression import block_bootstrap, blocked_cv, robust_fit
from droneid.dataset.validation import time_blocks

__all__ = ["TermModel", "split_terms", "prior_terms", "defined_rows", "defined_samples", "PhysicalFit", "physical_fit", "constancy_of", "IDENTIFIABLE_REL", "VIF_LIMIT", "drag_slope",
           "nested_functions", "drop_negligible", "trim_terms", "plausible"]


@dataclass(frozen=True)
class TermModel:
    """``y = offset + intercept + Σ coefs[i] · terms[i]``; ``labels`` name the terms (for the
    report). ``lo``/``hi``: each term's coefficient bounds (physics; missing = free, equal = fixed);
    ``intercept_bounds``: the intercept's (``(0, 0)``: no intercept, e.g. free fall at zero thrust);
    ``offset``: known physics with a fixed coefficient 1 (gravity), never fitted. :meth:`fit` is
    the robust, bounded least squares of :func:`droneid.core.regression.robust_fit`."""
    terms: tuple
    labels: tuple
    coefs: tuple = ()
    intercept: float = 0.0
    lo: tuple = ()
    hi: tuple = ()
    intercept_bounds: tuple = (-math.inf, math.inf)
    offset: sp.Expr = sp.Integer(0)
    at_bound: tuple = ()

    @classmethod
    def of(cls, features, labels=None, *, intercept_bounds=(-math.inf, math.inf),
           offset=sp.Integer(0)) -> "TermModel":
        """An unfitted model of prior features (:class:`priors.base.PriorFeature`, their
        ``bounds``) or plain sympy terms (free)."""
        feats = tuple(features)
        terms = tuple(getattr(f, "expr", f) for f in feats)
        labels = tuple(labels) if labels is not None else tuple(f"⟨{getattr(f, 'name', f)}⟩" for f in feats)
        bounds = [getattr(f, "bounds", (-math.inf, math.inf)) for f in feats]
        return cls(terms, labels, lo=tuple(b[0] for b in bounds), hi=tuple(b[1] for b in bounds),
                   intercept_bounds=tuple(intercept_bounds), offset=sp.sympify(offset))

    def extended(self, terms, labels) -> "TermModel":
        """This model's terms (and bounds) followed by free ``terms`` (evolved ones)."""
        k = len(self.terms)
        lo, hi = self.bounds()
        return TermModel(self.terms + tuple(terms), self.labels + tuple(labels),
                         lo=tuple(lo[:k]) + (-math.inf,) * len(terms), hi=tuple(hi[:k]) + (math.inf,) * len(terms),
                         intercept_bounds=self.intercept_bounds, offset=self.offset)

    def keep(self, idx) -> "TermModel":
        """The unfitted model of the terms ``idx`` (bounds kept)."""
        lo, hi = self.bounds()
        return TermModel(tuple(self.terms[i] for i in idx), tuple(self.labels[i] for i in idx),
                         lo=tuple(lo[i] for i in idx), hi=tuple(hi[i] for i in idx),
                         intercept_bounds=self.intercept_bounds, offset=self.offset)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of every coefficient, the intercept last."""
        k = len(self.terms)
        lo = np.array([*(self.lo or ()), *([-math.inf] * (k - len(self.lo or ())))], float)
        hi = np.array([*(self.hi or ()), *([math.inf] * (k - len(self.hi or ())))], float)
        return np.append(lo, self.intercept_bounds[0]), np.append(hi, self.intercept_bounds[1])

    def design(self, columns: Mapping[str, np.ndarray], n: int) -> np.ndarray:
        """(n, k+1): one column per term, then ones."""
        cols = [evaluate_expr(t, columns, n) for t in self.terms]
        return np.column_stack([*cols, np.ones(n)]) if cols else np.ones((n, 1))

    def _offset(self, columns, n) -> np.ndarray:
        return evaluate_expr(self.offset, columns, n)

    def _problem(self, columns, y) -> tuple:
        """(design, target less the fixed offset, lo, hi): what every fit of this model solves."""
        lo, hi = self.bounds()
        return self.design(columns, y.size), y - self._offset(columns, y.size), lo, hi

    def fit(self, columns: Mapping[str, np.ndarray], y: np.ndarray) -> "TermModel":
        f = robust_fit(*self._problem(columns, y))
        beta = f.beta
        return replace(self, coefs=tuple(float(b) for b in beta[:-1]), intercept=float(beta[-1]),
                       at_bound=tuple(bool(a) for a in f.at_bound[:-1]))

    def predict(self, columns: Mapping[str, np.ndarray], n: int) -> np.ndarray:
        return self.design(columns, n) @ np.array([*self.coefs, self.intercept]) + self._offset(columns, n)

    def cv_predictions(self, columns, y, blocks) -> np.ndarray:
        """Held-out predictions of the training rows (blocked CV, robust and bounded)."""
        A, yy, lo, hi = self._problem(columns, y)
        return blocked_cv(A, yy, blocks, lo, hi) + (y - yy)

    def cv_rmse(self, columns, y, blocks) -> float:
        return rmse(self.cv_predictions(columns, y, blocks), y)

    def intervals(self, columns, y, blocks, *, seed: int = 0) -> dict[str, tuple[float, float]]:
        """{label: (low, high)}: 95 % block-bootstrap interval of each coefficient ("intercept"
        too, unless it is fixed), :func:`droneid.core.regression.block_bootstrap` over ``blocks``."""
        A, yy, lo, hi = self._problem(columns, y)
        iv = block_bootstrap(A, yy, blocks, robust_fit(A, yy, lo, hi), lo, hi, seed=seed)
        out = {lab: (float(a), float(b)) for lab, (a, b) in zip(self.labels, iv[:-1])}
        if lo[-1] != hi[-1]:
            out["intercept"] = (float(iv[-1, 0]), float(iv[-1, 1]))
        return out

    def expr(self) -> sp.Expr:
        """The fitted model as one sympy expression."""
        return self.offset + sp.Float(self.intercept) + sp.Add(*[sp.Float(c) * t for c, t in zip(self.coefs, self.terms)])


#: a physical coefficient whose 95 % interval is wider than ± this fraction of max(|value|, its
#: nominal 1) is not identifiable from the flights: it is held at its nominal value
IDENTIFIABLE_REL = 0.5
#: a physical term whose column has a variance inflation factor above this is collinear with
#: the others (the data cannot separate them): it is held at its nominal value
VIF_LIMIT = 100.0


def defined_rows(features, columns: Mapping[str, np.ndarray], n: int) -> tuple[np.ndarray, list[str]]:
    """(mask of the rows where every feature is finite, ["name on k", ...] for the features that
    are not finite somewhere): a share of thrust, say, is 0/0 where every motor stops."""
    ok, bad = np.ones(n, bool), []
    for f in features:
        fin = np.isfinite(evaluate_expr(f.expr, columns, n))
        if not fin.all():
            bad.append(f"{f.name} on {int((~fin).sum())}")
            ok &= fin
    return ok, bad


def defined_samples(cs, features):
    """(constraint samples without those where a feature is not finite, how many were left out):
    a constraint at zero thrust says nothing about a feature that is undefined there."""
    if cs is None or not len(cs):
        return cs, 0
    ok, _ = defined_rows(features, {n: cs.X[:, i] for i, n in enumerate(cs.input_names)}, len(cs))
    return (cs if ok.all() else cs.where(ok)), int((~ok).sum())


def split_terms(prior, target: str) -> tuple:
    """The prior's terms as separate features, without constant ones (the intercept holds them,
    or the prior's fixed offset when the constant is known physics: gravity)."""
    return tuple(f for f in prior.features(target) if f.expr.free_symbols)


def prior_terms(prior, target: str, features: Sequence | None = None) -> TermModel:
    """The unfitted refit model of ``target``: the prior's terms (or ``features``: its terms and
    effects) with their physical bounds, its fixed offset (gravity) and its intercept bounds."""
    feats = split_terms(prior, target) if features is None else tuple(features)
    return TermModel.of(feats, intercept_bounds=prior.intercept_bounds(target), offset=prior.offset(target))


@dataclass(frozen=True)
class PhysicalFit:
    """A fitted model with its evidence: ``model`` (fitted), ``intervals`` {label: (low, high)}
    (95 %: the block bootstrap, and for a vehicle constant fitted on several flights its hull
    with the between-flight interval, :mod:`droneid.fitting.constancy`), ``held`` {label: value} (not
    identifiable, held at the nominal value), ``at_bound`` {label: bound} (the data pull the
    coefficient outside its physical range: it sits on the bound), ``notes`` (one line per held
    or bounded coefficient), ``constancy`` {label: :class:`~droneid.fitting.constancy.Constancy`} of
    every vehicle constant fitted (empty without the rows' flights)."""
    model: TermModel
    intervals: dict
    held: dict
    at_bound: dict
    notes: tuple = ()
    constancy: dict = field(default_factory=dict)


def _vif(A: np.ndarray, j: int, with_intercept: bool) -> float:
    others = np.delete(A, j, axis=1)
    if not with_intercept:
        others = others[:, :-1]
    c = A[:, j]
    if others.shape[1] == 0 or not np.std(c) > 0:
        return 1.0
    beta = np.linalg.lstsq(others, c, rcond=None)[0]
    res = c - others @ beta
    ss = float(np.sum((c - (c.mean() if with_intercept else 0.0)) ** 2))
    r2 = 1.0 - float(np.sum(res * res)) / ss if ss > 0 else 0.0
    return math.inf if r2 >= 1.0 else 1.0 / (1.0 - r2)


def physical_fit(model: TermModel, columns, y, blocks, *, seed: int = 0, n_physical: int | None = None,
                 flight=None, t=None, sources: Sequence[str] = (), alternatives: Sequence[tuple] = ()) -> PhysicalFit:
    """Fit ``model`` (robust, bounded), give every coefficient its 95 % block-bootstrap interval
    (``blocks``: time blocks of the training flights), and hold at its nominal value 1 each of the
    first ``n_physical`` terms (default: every term with a physical bound) that the data cannot pin
    down: interval wider than ±:data:`IDENTIFIABLE_REL` of max(|value|, 1), or collinear (VIF >
    :data:`VIF_LIMIT`). Physical terms collinear with each other are first tied into one term, their
    sum with one fitted scale (:func:`_tie_collinear`): a pair is never held at nominal values
    nobody measured. Evolved and effect terms (free) are reported, never held.

    With the rows' ``flight`` ids and times ``t`` (``sources``: the flights' names), every
    vehicle constant left free (a term with a physical bound: thrust, tilt, drag) also gets its
    constancy across flights or stretches of one flight (:func:`constancy_of`), and with several
    flights its interval becomes the hull of the bootstrap's and the between-flight one.

    ``alternatives``: ((label, columns, y, columns_same, y_same), ...), rows read as another
    admitted choice of the data reads them (e.g. the thrust inputs at every offset the data do not
    reject) and the same rows as read here: each coefficient's interval also spans its value moved
    by the difference of the two refits (the choice's own uncertainty, which no bootstrap at one
    choice can see)."""
    model, n_physical, notes = _tie_collinear(model, columns, y.size, n_physical)
    lo, hi = model.bounds()
    k = len(model.terms)
    phys = [i for i in range(k if n_physical is None else n_physical)
            if (np.isfinite(lo[i]) or np.isfinite(hi[i])) and lo[i] != hi[i]]
    fitted = model.fit(columns, y)
    iv = fitted.intervals(columns, y, blocks, seed=seed)
    A = model.design(columns, y.size)
    free_int = lo[-1] != hi[-1]
    held = {}
    for i in phys:
        lab = model.labels[i]
        a, b = iv[lab]
        half = (b - a) / 2
        vif = _vif(A, i, free_int)
        if half > IDENTIFIABLE_REL * max(abs(fitted.coefs[i]), 1.0) or vif > VIF_LIMIT:
            nominal = float(np.clip(1.0, lo[i], hi[i]))
            held[lab] = nominal
            why = (f"collinear with the other terms (VIF {vif:.3g} > {VIF_LIMIT:g})" if vif > VIF_LIMIT else
                   f"its 95 % interval [{a:.3g}, {b:.3g}] is wider than ±{100 * IDENTIFIABLE_REL:.0f} %")
            notes.append(f"{lab} is not identifiable from these flights ({why}): held at its nominal "
                         f"value {nominal:g}")
    if held:
        lo2, hi2 = lo[:k].copy(), hi[:k].copy()
        for i, lab in enumerate(model.labels):
            if lab in held:
                lo2[i] = hi2[i] = held[lab]
        model = replace(model, lo=tuple(lo2), hi=tuple(hi2))
        fitted = model.fit(columns, y)
        iv = fitted.intervals(columns, y, blocks, seed=seed)
    at_bound = {}
    for i, lab in enumerate(model.labels):
        if i < len(fitted.at_bound) and fitted.at_bound[i] and lab not in held:
            c = fitted.coefs[i]
            at_bound[lab] = c
            notes.append(f"{lab} sits on its physical bound {c:g}: the data pull it outside "
                         f"[{lo[i]:g}, {hi[i]:g}] (e.g. negative drag); the bound holds")
    constancy = {}
    if flight is not None and t is not None:
        constancy = constancy_of(model, columns, y, [i for i in phys if model.labels[i] not in held],
                                 np.asarray(flight), np.asarray(t), sources, seed=seed)
        for i, lab in enumerate(model.labels):
            c = constancy.get(lab)
            if c is not None and c.between is not None:   # the hull, within the physical range
                a, b = iv[lab]
                iv[lab] = (max(min(a, c.between[0]), lo[i]), min(max(b, c.between[1]), hi[i]))
    if alternatives:
        iv = _spanning(fitted, iv, alternatives)
        notes.append("the 95 % intervals also span each coefficient refit with the thrust inputs read at "
                     + ", ".join(str(a[0]) for a in alternatives)
                     + " (every other offset the data do not reject: the offset's own uncertainty)")
    return PhysicalFit(fitted, iv, held, at_bound, tuple(notes), constancy)


def _spanning(fitted: TermModel, iv: dict, alternatives: Sequence[tuple]) -> dict:
    """``iv`` with each coefficient's interval widened to its value in ``fitted`` moved by the
    difference of two refits of the model (its holds kept) on each alternative ``(label, columns,
    y, columns_same, y_same)``: the rows as the other choice reads them less the same rows as read
    here."""
    out = dict(iv)
    lo, hi = fitted.bounds()
    for _, cols, yy, cols0, yy0 in alternatives:
        if len(yy) <= len(fitted.terms):
            continue
        moved = np.asarray(fitted.fit(cols, yy).coefs) - np.asarray(fitted.fit(cols0, yy0).coefs)
        for i, (lab, c0, dc) in enumerate(zip(fitted.labels, fitted.coefs, moved)):
            c = float(np.clip(c0 + dc, lo[i], hi[i]))     # within the physical range
            if lab in out and np.isfinite(c):
                a, b = out[lab]
                out[lab] = (min(a, c), max(b, c))
    return out


def _physical_indices(model: TermModel, n_physical: int | None) -> list[int]:
    lo, hi = model.bounds()
    return [i for i in range(len(model.terms) if n_physical is None else n_physical)
            if (np.isfinite(lo[i]) or np.isfinite(hi[i])) and lo[i] != hi[i]]


def _tie_collinear(model: TermModel, columns, n: int, n_physical: int | None) -> tuple:
    """(model, n_physical, notes): two or more physical terms with the same bounds that are
    collinear with each other (VIF > :data:`VIF_LIMIT` each, and each nearly a combination of
    the others alone) become ONE term, their sum at its nominal scale with one fitted
    coefficient: the data identify that combination and nothing else, so neither term is held
    at a nominal value nobody measured (issue 36). Unchanged without such a group."""
    phys = _physical_indices(model, n_physical)
    if len(phys) < 2:
        return model, n_physical, []
    lo, hi = model.bounds()
    A = model.design(columns, n)
    free_int = lo[-1] != hi[-1]
    vif = {i: _vif(A, i, free_int) for i in phys}
    group = [i for i in phys if vif[i] > VIF_LIMIT]
    if len(group) < 2 or len({(lo[i], hi[i]) for i in group}) != 1:
        return model, n_physical, []
    sub = A[:, group + [A.shape[1] - 1]]      # _vif reads the last column as the intercept's
    if min(_vif(sub, j, free_int) for j in range(len(group))) <= VIF_LIMIT:
        return model, n_physical, []    # collinear with other terms, not within the group
    first = group[0]
    keep = [i for i in range(len(model.terms)) if i not in group[1:]]
    terms = [sp.Add(*[model.terms[i] for i in group]) if i == first else model.terms[i] for i in keep]
    label = "⟨" + " + ".join(model.labels[i].strip("⟨⟩") for i in group) + "⟩"
    labels = [label if i == first else model.labels[i] for i in keep]
    tied = TermModel(tuple(terms), tuple(labels), lo=tuple(lo[i] for i in keep), hi=tuple(hi[i] for i in keep),
                     intercept_bounds=model.intercept_bounds, offset=model.offset)
    note = (f"{', '.join(model.labels[i] for i in group)} are collinear (VIF "
            f"{', '.join(f'{vif[i]:.3g}' for i in group)} > {VIF_LIMIT:g}): the data identify only their "
            f"sum, fitted as one scale {label} (their nominal ratio kept)")
    return tied, (None if n_physical is None else n_physical - len(group) + 1), [note]


def constancy_of(model: TermModel, columns, y, which: Sequence[int], flight: np.ndarray, t: np.ndarray,
                 sources: Sequence[str] = (), *, seed: int = 0, free: Sequence[int] | None = None,
                 describe: Sequence[int] = ()) -> dict:
    """{label: :class:`~droneid.fitting.constancy.Constancy`} of the coefficients ``which`` (indices of
    ``model``'s vehicle constants): ``model`` (its held values and bounds, the constants' own
    physics bounds dropped: :func:`droneid.fitting.constancy.unit_bounds`; ``free``, when given,
    the constants whose bounds are dropped, a superset of ``which``) fitted on every
    training flight alone, or on every stretch of the one flight (:func:`droneid.fitting.constancy.units_of`),
    each with its block-bootstrap standard error over its own time blocks (inflated by
    B/(B − 1) for B blocks), tested and combined by :func:`droneid.fitting.constancy.heterogeneity`, flagged
    by Holm over ``which`` (:func:`droneid.fitting.constancy.holm_flags`). The coefficients
    ``describe`` (a flight condition fitted per unit) are returned beside them, untested: their
    per-unit values and 95 % intervals only (p NaN, ``constant`` None), every unit kept."""
    if not which:
        return {}
    unit, names, kind = units_of(t, flight, sources)
    lo, hi = unit_bounds(*model.bounds(), tested=which if free is None else free)
    vals, ses, ivs, dfs, used = [], [], [], [], []
    for u, name in enumerate(names):
        rows = np.flatnonzero(unit == u)
        if rows.size < MIN_UNIT_ROWS:
            continue
        sub = {n: np.asarray(v)[rows] for n, v in columns.items()}
        A, yy, _, _ = model._problem(sub, np.asarray(y, float)[rows])
        fit, se, pct, dof = unit_estimate(A, yy, time_blocks(t[rows], np.zeros(rows.size, int)), lo, hi, seed=seed)
        vals.append(fit.beta)
        ses.append(se)
        ivs.append(pct)
        dfs.append(dof)
        used.append(name)
    out = constancies(kind, used, vals, ses, ivs, {i: model.labels[i] for i in which},
                      {i: _physical_scale(model.terms[i]) for i in which}, dfs)
    for i in describe if len(used) >= 2 else ():
        out[model.labels[i]] = Constancy(kind, {name: (float(v[i]), float(iv[0, i]), float(iv[1, i]))
                                                for name, v, iv in zip(used, vals, ivs)}, math.nan, None)
    return out


def _physical_scale(term: sp.Expr) -> tuple[float, str] | None:
    """(k, "1/s") for a linear drag term written ``−k·v`` on one velocity (its coefficient times k
    is the drag in 1/s), else None."""
    syms = term.free_symbols
    if len(syms) != 1:
        return None
    v = next(iter(syms))
    if v.name not in ("vx", "vy", "vz"):
        return None
    c = sp.simplify(term / v)
    return (float(-c), "1/s") if c.is_number and float(c) < 0 else None


#: an evolved term with more operations than this is not something a person can read aloud
MAX_TERM_OPS = 10


def nested_functions(expr: sp.Expr) -> int:
    """How deeply non-polynomial functions (sin, cos, exp, tanh, |.|, ...) nest in ``expr``:
    sin(vx) is 1, sin(cos(vx)) is 2 (a person can read the first aloud, not the second)."""
    def depth(e):
        inner = max((depth(a) for a in e.args), default=0)
        return inner + 1 if isinstance(e, sp.Function) else inner
    return depth(expr)


def trim_terms(model: TermModel, columns, y, blocks, keep_first: int, margin: float = 0.01,
               corr_limit: float = 0.999, max_ops: int = MAX_TERM_OPS, cancel_limit: float = 3.0,
               sizes: Sequence[int] | None = None) -> tuple[TermModel, list[str]]:
    """Drop evolved terms (index ≥ ``keep_first``) that do not earn their place.

    1. A term whose column correlates with an earlier one beyond ``corr_limit`` (a cancelling
       pair or a near-duplicate) is dropped (least squares refits the survivor).
       Terms with more than ``max_ops`` sympy operations (``sizes``: counted on the form a
       person reads, e.g. with a named prior feature as one symbol) or with a function inside a
       function (sin(cos(.)), :func:`nested_functions`) go too (unreadable). While the terms'
       contributions Σ|b_i|·std(col_i) exceed ``cancel_limit`` times the spread of their sum
       (times the physical terms' own ratio when that is above 1: a command map a Σu² + b Σu
       offsets by design), the evolved term contributing most goes (a cancelling pair such as
       22.9·cos a − 21.7·cos b fits the training range and explodes outside it).
    2. Backward elimination on the blocked-CV error: the evolved term whose removal costs least
       goes while the CV error rises by less than ``margin`` (relative).
    Returns the refit model and one line per dropped term.
    """
    n = y.size
    cols = [evaluate_expr(t, columns, n) for t in model.terms]
    notes = []
    keep = []
    for i, c in enumerate(cols):
        dup = None
        if i >= keep_first and np.std(c) > 0 and np.all(np.isfinite(c)):
            for j in keep:
                cj = cols[j]
                if np.std(cj) > 0 and abs(np.corrcoef(c, cj)[0, 1]) > corr_limit:
                    dup = j
                    break
        elif i >= keep_first:
            dup = -1
        size = sizes[i] if sizes is not None else sp.count_ops(model.terms[i])
        if dup is None and i >= keep_first and (size > max_ops or nested_functions(model.terms[i]) > 1):
            dup = -2
        if dup is None:
            keep.append(i)
        else:
            why = {-1: "not finite or constant on the training data",
                   -2: f"more than {max_ops} operations or functions of functions (unreadable)"}.get(dup)
            notes.append(f"dropped {model.labels[i]}: " + (why or f"duplicates {model.labels[dup]}"))

    def cv(idx):
        return model.keep(idx).cv_rmse(columns, y, blocks)

    def cancellation(idx):
        """Σ|b_i|·std(col_i) over the spread of their sum: ≫ 1 when terms cancel each other."""
        beta = model.keep(idx).fit(columns, y).coefs
        parts = [b * cols[i] for b, i in zip(beta, idx)]
        spread = float(np.std(np.sum(parts, axis=0)))
        return {i: abs(b) * float(np.std(cols[i])) for b, i in zip(beta, idx)}, spread

    def ratio(idx):
        contrib, spread = cancellation(idx)
        return sum(contrib.values()) / max(spread, 1e-12), contrib

    # the physical terms may offset each other by design (a command map a Σu² + b Σu): only
    # cancellation beyond theirs counts against evolved terms
    base = [i for i in keep if i < keep_first]
    limit = cancel_limit * max(1.0, ratio(base)[0] if base else 1.0)
    while True:  # cancelling pairs: big opposite contributions that nearly sum to nothing
        r, contrib = ratio(keep)
        evolved = [i for i in keep if i >= keep_first]
        if not evolved or r <= limit:
            break
        i = max(evolved, key=lambda k: contrib[k])
        keep.remove(i)
        notes.append(f"dropped {model.labels[i]}: it cancels other terms (contributions {r:.3g}x the "
                     f"spread of their sum, limit {limit:.3g}x)")

    cur = cv(keep)
    while True:
        evolved = [i for i in keep if i >= keep_first]
        if not evolved:
            break
        trials = {i: cv([k for k in keep if k != i]) for i in evolved}
        i = min(trials, key=trials.get)
        if trials[i] <= cur * (1.0 + margin):
            keep.remove(i)
            notes.append(f"dropped {model.labels[i]}: validation error {cur:.4g} -> {trials[i]:.4g} without it")
            cur = trials[i]
        else:
            break
    return model.keep(keep).fit(columns, y), notes


@dataclass(frozen=True)
class Plausibility:
    ok: bool
    max_abs: float
    bound: float
    n_points: int
    note: str = ""


def plausible(expr: sp.Expr, ranges: Mapping[str, tuple[float, float]], bound: float,
              margin: float = 0.2, n_points: int = 4000, seed: int = 0,
              fixed: Mapping[str, float] | None = None) -> Plausibility:
    """Whether ``expr`` stays within ±``bound`` on random points spanning every input's training
    range widened by ``margin`` of its span on each side (angles kept within ±80° for roll and
    pitch, where the thrust still holds the vehicle up)."""
    rng = np.random.default_rng(seed)
    names = sorted(s.name for s in expr.free_symbols)
    cols = {}
    for n in names:
        if n in (fixed or {}):
            cols[n] = np.full(n_points, float(fixed[n]))
            continue
        lo, hi = ranges.get(n, (0.0, 0.0))
        pad = margin * (hi - lo)
        lo, hi = lo - pad, hi + pad
        if n in ("roll", "pitch"):
            lo, hi = max(lo, -math.radians(80)), min(hi, math.radians(80))
        if n.startswith(("rpm", "motor")) or n in ("throttle", "thrust", "battery_voltage"):
            lo = max(lo, 0.0)
        cols[n] = rng.uniform(lo, hi, n_points)
    v = evaluate_expr(expr, cols, n_points)
    m = float(np.max(np.abs(v))) if np.all(np.isfinite(v)) else math.inf
    ok = m <= bound
    note = "" if ok else (f"reaches {m:.3g} (bound {bound:.3g}) on inputs within the training range "
                          f"± {100 * margin:.0f} %")
    return Plausibility(ok, m, float(bound), n_points, note)


def drag_slope(expr: sp.Expr, velocity: str, rows: Mapping[str, np.ndarray], v_max: float,
               n_points: int = 41) -> float:
    """The largest slope ∂v̇/∂v (1/s) of ``expr`` along its own-axis ``velocity`` from −v_max to
    v_max, every other input held at each of the given training ``rows`` (states the vehicle
    really flew). Drag grows with speed, so a physical model's slope is ≤ 0 (−k_D for linear
    drag); an evolved velocity term that oscillates or turns over shows a positive slope."""
    if velocity not in {s.name for s in expr.free_symbols}:
        return -math.inf
    m = len(next(iter(rows.values())))
    v = np.linspace(-v_max, v_max, n_points)
    cols = {k: np.repeat(np.asarray(a, float), n_points) for k, a in rows.items()}
    cols[velocity] = np.tile(v, m)
    vals = evaluate_expr(expr, cols, m * n_points).reshape(m, n_points)
    slopes = np.diff(vals, axis=1) / np.diff(v)
    return float(np.max(slopes)) if np.all(np.isfinite(slopes)) else math.inf


def drop_negligible(expr: sp.Expr, columns: Mapping[str, np.ndarray], n: int, rel: float = 1e-3) -> sp.Expr:
    """``expr`` without the addends of its sums that never reach ``rel`` of the sum's largest value
    on the training data (``4·roll²·rpm4² + rpm2 + 3.142`` -> ``4·roll²·rpm4²`` when rpm4 is
    ~10⁵): the same numbers to that precision, a shorter equation."""
    def walk(e):
        if not e.args:
            return e
        e = e.func(*[walk(a) for a in e.args]) if not isinstance(e, sp.Add) else e
        if isinstance(e, sp.Add):
            parts = [walk(a) for a in e.args]
            vals = [np.abs(evaluate_expr(a, columns, n)) for a in parts]
            if not all(np.all(np.isfinite(v)) for v in vals):
                return sp.Add(*parts)
            top = float(np.max(np.abs(evaluate_expr(sp.Add(*parts), columns, n)))) if n else 0.0
            keep = [a for a, v in zip(parts, vals) if float(np.max(v, initial=0.0)) >= rel * top]
            return sp.Add(*keep) if keep else sp.Add(*parts)
        return e
    return walk(expr)
