"""Safe parsing of user expressions (priors, constraints, ``--prior EXPR``) into sympy.

User text is parsed with :mod:`ast` and translated node by node into sympy objects: only numbers,
the allowed signal names and parameters, ``+ - * / ** ^``, unary minus and a whitelist of
functions are accepted. Nothing is ever passed to ``eval``/``sympify`` of a string.
"""
from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping

import numpy as np
import sympy as sp

from .errors import ConfigError, did_you_mean

__all__ = ["parse_expression", "ALLOWED_FUNCTIONS", "compile_expression", "symbol"]

#: Functions a user expression may call, by name.
ALLOWED_FUNCTIONS: Mapping[str, object] = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos,
    "atan": sp.atan, "atan2": sp.atan2, "sinh": sp.sinh, "cosh": sp.cosh, "tanh": sp.tanh,
    "exp": sp.exp, "log": sp.log, "sqrt": sp.sqrt, "abs": sp.Abs, "sign": sp.sign,
    "min": sp.Min, "max": sp.Max,
}
_CONSTANTS = {"pi": sp.pi, "e": sp.E}
_BINOPS = {
    ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b, ast.Pow: lambda a, b: a ** b,
}
_MAX_LEN = 2000


def symbol(name: str) -> sp.Symbol:
    """The sympy symbol droneid uses for a signal: real-valued, named as the signal."""
    return sp.Symbol(name, real=True)


def parse_expression(text: str, signals: Iterable[str], params: Mapping[str, float] | None = None,
                     what: str = "expression") -> sp.Expr:
    """Parse ``text`` into a sympy expression over the symbols named in ``signals``.

    ``params`` are named numbers substituted as constants (e.g. ``{"g": 9.81, "k_D": 0.28}``).
    Raises :class:`ConfigError` naming ``what`` and the offending part for anything else.
    """
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(f"{what}: empty expression")
    if len(text) > _MAX_LEN:
        raise ConfigError(f"{what}: expression longer than {_MAX_LEN} characters")
    signals = list(signals)
    params = dict(params or {})
    names = {n: symbol(n) for n in signals}
    try:
        # '^' means power (as in maths); Python would read it as xor with the wrong precedence
        tree = ast.parse(text.strip().replace("^", "**"), mode="eval")
    except SyntaxError as exc:
        raise ConfigError(f"{what}: cannot parse {text!r}: {exc.msg}") from None

    def conv(node):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            return sp.Float(node.value) if isinstance(node.value, float) else sp.Integer(node.value)
        if isinstance(node, ast.Name):
            if node.id in names:
                return names[node.id]
            if node.id in params:
                return sp.Float(float(params[node.id]))
            if node.id in _CONSTANTS:
                return _CONSTANTS[node.id]
            raise ConfigError(
                f"{what}: unknown name '{node.id}' in {text!r}"
                f"{did_you_mean(node.id, [*names, *params, *_CONSTANTS])}; "
                f"signals available: {', '.join(signals) or 'none'}")
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            return _BINOPS[type(node.op)](conv(node.left), conv(node.right))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = conv(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in ALLOWED_FUNCTIONS:
                fname = node.func.id if isinstance(node.func, ast.Name) else ast.unparse(node.func)
                raise ConfigError(
                    f"{what}: function '{fname}' is not allowed in {text!r}"
                    f"{did_you_mean(fname, ALLOWED_FUNCTIONS)}; allowed: {', '.join(ALLOWED_FUNCTIONS)}")
            if node.keywords:
                raise ConfigError(f"{what}: keyword arguments are not allowed in {text!r}")
            return ALLOWED_FUNCTIONS[node.func.id](*[conv(a) for a in node.args])
        raise ConfigError(f"{what}: '{ast.unparse(node)}' is not allowed in {text!r} "
                          "(only numbers, signal names, + - * / ** and whitelisted functions)")

    try:
        expr = conv(tree.body)
    except TypeError as exc:  # wrong number of function arguments
        raise ConfigError(f"{what}: {exc} in {text!r}") from None
    return sp.sympify(expr)


def compile_expression(expr: sp.Expr, names: Iterable[str]):
    """A numpy function ``f(columns: Mapping[str, ndarray]) -> ndarray`` evaluating ``expr``.

    The function broadcasts constants to the length of the columns and never raises on
    overflow or domain errors (those become inf/nan, which callers check).
    """
    names = list(names)
    syms = [symbol(n) for n in names]
    fn = sp.lambdify(syms, expr, modules="numpy")
    used = {s.name for s in expr.free_symbols}

    def evaluate(columns: Mapping[str, np.ndarray]) -> np.ndarray:
        n = len(next(iter(columns.values()))) if columns else 1
        args = [np.asarray(columns[nm], dtype=float) if nm in used else np.zeros(n) for nm in names]
        with np.errstate(all="ignore"):
            out = np.asarray(fn(*args), dtype=float)
        return np.broadcast_to(out, (n,)).copy() if out.ndim == 0 or out.size == 1 else out

    return evaluate
