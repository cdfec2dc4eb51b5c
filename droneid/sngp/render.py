"""The symbolic side of a fitted SNGP model: node expressions, the simplified equation and its
forms, the archive's lazily built equations, and the background import of sympy.

sympy is imported only here (and in :mod:`droneid.sngp.model`), inside the functions that need
it: a fit without priors runs its whole search before sympy is imported, while
:func:`import_symbolic_side` imports it in a background thread (the search kernels release the
GIL), so a fresh process such as ``droneid fit`` does not wait for the import on top of the
search.
"""
from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING

from droneid.sngp import kernels as K
from droneid.sngp.operators import CONST, IDENT, by_code
from droneid.core.lazy import lazy_module

#: the expression tools (sympy): loaded when a model is first written as an equation
_expressions = lazy_module("droneid.core.expressions")

if TYPE_CHECKING:
    import sympy as sp

    from droneid.sngp.model import SymbolicModel
    from droneid.sngp.population import Population

__all__ = ["ArchiveEntry", "node_exprs", "render", "links_equation", "guarded_simplify",
           "is_sympy", "import_symbolic_side"]


def node_exprs(pop: "Population", names, prior_syms):
    """A memoised ``expr(node) -> sympy expression`` over ``pop``'s links: the inputs ``names``
    and prior terminals ``prior_syms`` as symbols, head nodes as their (constant) values."""
    import sympy as sp

    consts = (sp.Integer(0), sp.Rational(1, 2), sp.Integer(1), sp.Integer(2), sp.Integer(3), sp.pi)
    lay = pop.lay
    head_end, tail0 = int(lay[K.L_HEAD]), int(lay[K.L_TAIL])
    terminals = [_expressions.symbol(n) for n in names] + [_expressions.symbol(s) for s in prior_syms]
    memo: dict[int, "sp.Expr"] = {}

    def expr(n: int) -> "sp.Expr":
        if n in memo:
            return memo[n]
        code = int(pop.op[n])
        if code == CONST:
            e = consts[n] if n < len(consts) else sp.Float(pop.cval[n])
        elif n < head_end:
            e = sp.Float(float(pop.current(n)[0]))
        elif n < tail0:
            e = terminals[n - head_end]
        elif code == IDENT:
            e = expr(int(pop.a[n]))
        else:
            op = by_code(code)
            args = [expr(int(pop.a[n]))] + ([expr(int(pop.b[n]))] if op.arity == 2 else [])
            e = op.sympy(*args)
        memo[n] = e
        return e
    return expr


def render(model: "SymbolicModel", prior_syms, prior_labels, prior_exprs, simplify_s: float) -> dict:
    """Simplified forms of ``model``: ``equation_``, ``expr_``, ``expr_raw_``, ``latex_``,
    ``coef_``, ``prior_coef_`` (see :class:`~droneid.sngp.estimator.SNGPRegressor`). Each evolved
    term is simplified by sympy within what is left of ``simplify_s`` seconds (0: none)."""
    import sympy as sp

    deadline = time.perf_counter() + float(simplify_s)
    prior_set = {_expressions.symbol(s) for s in prior_syms}
    simple_terms = []
    for t in model.terms:
        left = deadline - time.perf_counter()
        simple_terms.append(guarded_simplify(t, left) if t not in prior_set else t)
    coef = {}
    prior_coef = {prior_labels[s]: 0.0 for s in prior_syms}
    display = sp.Float(model.intercept)
    for t, st, c in zip(model.terms, simple_terms, model.coefs):
        if t in prior_set:
            prior_coef[prior_labels[t.name]] = c
        else:
            key = _expressions.to_text(st)
            coef[key] = coef.get(key, 0.0) + c
        display = display + sp.Float(c) * st
    shown = _expressions.round_expr(display)
    return {"coef_": coef, "prior_coef_": prior_coef,
            "expr_raw_": model.expression(expand_priors=True),
            "expr_": display.xreplace({_expressions.symbol(s): e for s, e in prior_exprs.items()}),
            "equation_": _expressions.to_text(shown), "latex_": sp.latex(shown)}


def links_equation(pop: "Population", names, prior_syms) -> str:
    """The rounded equation of ``pop``'s current model (an archived model of the constrained
    search), unsimplified."""
    import sympy as sp

    node_expr = node_exprs(pop, names, prior_syms)
    expr = sp.Integer(0)
    for c, bta in zip(pop.cols, pop.beta):
        if c == -1:
            expr += sp.Float(float(bta))
        elif c >= 0 and bta != 0.0:
            expr += sp.Float(float(bta)) * node_expr(int(c))
    return _expressions.to_text(_expressions.round_expr(expr))


class ArchiveEntry(Mapping):
    """One non-dominated model of the constrained search: a read-only mapping with the keys
    ``rmse_train``, ``constraint_rmse_train`` and ``equation``. The equation is built with sympy
    only when first read (a run archives up to 64 models and most callers read the errors)."""

    _KEYS = ("rmse_train", "constraint_rmse_train", "equation")

    def __init__(self, rmse_train: float, constraint_rmse_train: float, equation):
        self._values = {"rmse_train": float(rmse_train),
                        "constraint_rmse_train": float(constraint_rmse_train)}
        self._equation = equation

    def __getitem__(self, key):
        if key == "equation" and key not in self._values:
            self._values[key] = self._equation()
        if key not in self._KEYS:
            raise KeyError(key)
        return self._values[key]

    def __iter__(self):
        return iter(self._KEYS)

    def __len__(self) -> int:
        return len(self._KEYS)

    def __repr__(self) -> str:
        return f"ArchiveEntry({dict(self)!r})"


class _Timeout(Exception):
    pass


def guarded_simplify(expr: "sp.Expr", seconds: float, max_ops: int = 60) -> "sp.Expr":
    """sympy.simplify with a wall-clock limit (SIGALRM in the main thread) and a size cap.

    Returns ``expr`` unchanged when it is too big, time runs out, or the result is not smaller.
    """
    import sympy as sp
    if seconds <= 0.01 or sp.count_ops(expr) > max_ops:
        return expr
    in_main = threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")
    if not in_main:
        if sp.count_ops(expr) > 15:
            return expr
        try:
            out = sp.simplify(expr)
        except Exception:   # noqa: BLE001 - simplification is optional
            return expr
    else:
        active = [True]

        def _alarm(signum, frame):
            if not active[0]:
                return
            # Raise only inside sympy: a signal can also land in foreign code run meanwhile
            # (a gc callback, a __del__) that would swallow the exception. Re-arm either way,
            # so the next tick ends the simplification if this one does not.
            signal.setitimer(signal.ITIMER_REAL, 0.02)
            where = frame.f_code.co_filename if frame is not None else ""
            if "sympy" in where or "mpmath" in where or where == __file__:
                raise _Timeout()
        old = signal.signal(signal.SIGALRM, _alarm)
        try:
            try:
                signal.setitimer(signal.ITIMER_REAL, min(seconds, 1.0))
                out = sp.simplify(expr)
            finally:
                active[0] = False
                signal.setitimer(signal.ITIMER_REAL, 0)
        except _Timeout:
            return expr
        except Exception:   # noqa: BLE001 - simplification is optional
            return expr
        finally:
            signal.signal(signal.SIGALRM, old if old is not None else signal.SIG_DFL)
    return out if sp.count_ops(out) <= sp.count_ops(expr) else expr


def is_sympy(obj) -> bool:
    """Whether ``obj`` is a sympy object (without importing sympy: none exists before it is)."""
    # sympy.core.basic, not sympy: another thread may be importing sympy (import_symbolic_side),
    # and a half-imported sympy has no Basic yet; no object is a Basic before its class exists
    basic = sys.modules.get("sympy.core.basic")
    return basic is not None and isinstance(obj, getattr(basic, "Basic", ()))


def import_symbolic_side() -> None:
    """Import the modules of the model and its rendering (sympy, ~0.3 s) in a background thread
    when nothing imported them yet: called as the search starts, whose kernels release the GIL,
    so the import overlaps the search instead of adding to it. Imports only: results are the
    same with or without it."""
    if "sympy" in sys.modules:
        return
    threading.Thread(target=_import_quietly, args=(f"{__package__}.model",),
                     name="droneid-import-sympy", daemon=True).start()


def _import_quietly(name: str) -> None:
    """Import ``name``, then run a full garbage collection: the import's many new objects would
    otherwise still be young when the equation is built, and the collections scanning them would
    add to it (~0.07 s CPU measured); here, on the other core while the search runs, they cost
    the user nothing."""
    import gc
    import importlib
    try:
        importlib.import_module(name)
    except Exception:   # noqa: BLE001 - the main thread's own import of it reports the error
        return
    gc.collect()
