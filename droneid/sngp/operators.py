"""The one operator table of the SNGP engine.

Every function a node may compute is listed once here, by name, with its integer code (what the
numba kernels in :mod:`droneid.sngp.kernels` dispatch on), its arity, a numpy kernel (used to
predict with a saved model and to cross-check the compiled kernel in the tests), a sympy
constructor (how it appears in an equation) and a complexity weight.

Codes below 10 are structural node kinds, not functions.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["Operator", "OPERATORS", "HEAD_OPERATORS", "DEFAULT_FUNCTIONS", "by_name", "by_code",
           "CONST", "VAR", "IDENT"]

# structural node kinds
CONST, VAR, IDENT = 0, 1, 2

#: A node whose value would exceed this magnitude is invalid (cubes overflow quietly).
MAX_ABS = 1e12
#: Protected division: a denominator below this magnitude fails (head block: proxy constant).
DIV_EPS = 1e-12


@dataclass(frozen=True)
class Operator:
    name: str
    code: int
    arity: int
    numpy: Callable
    sympy: Callable
    complexity: int
    description: str


def _sp():
    """sympy, imported when an equation is first built (the search itself never needs it)."""
    import sympy
    return sympy


def _pdiv_np(a, b):
    with np.errstate(all="ignore"):
        return np.where(np.abs(b) > DIV_EPS, a / np.where(np.abs(b) > DIV_EPS, b, 1.0), np.nan)


OPERATORS: tuple[Operator, ...] = (
    Operator("add", 10, 2, np.add, lambda a, b: a + b, 1, "a + b"),
    Operator("sub", 11, 2, np.subtract, lambda a, b: a - b, 1, "a - b"),
    Operator("mul", 12, 2, np.multiply, lambda a, b: a * b, 1, "a * b"),
    Operator("square", 13, 1, np.square, lambda a: a ** 2, 2, "a^2"),
    Operator("cube", 14, 1, lambda a: a * a * a, lambda a: a ** 3, 2, "a^3"),
    Operator("sin", 15, 1, np.sin, lambda a: _sp().sin(a), 3, "sin a"),
    Operator("cos", 16, 1, np.cos, lambda a: _sp().cos(a), 3, "cos a"),
    Operator("neg", 17, 1, np.negative, lambda a: -a, 1, "-a"),
    Operator("div", 18, 2, _pdiv_np, lambda a, b: a / b, 2,
             "a / b (invalid where |b| < 1e-12)"),
    Operator("sqrtabs", 19, 1, lambda a: np.sqrt(np.abs(a)), lambda a: _sp().sqrt(_sp().Abs(a)), 3,
             "sqrt(|a|)"),
    Operator("tan", 20, 1, np.tan, lambda a: _sp().tan(a), 3, "tan a"),
    Operator("abs", 21, 1, np.abs, lambda a: _sp().Abs(a), 2, "|a|"),
    Operator("exp", 22, 1, np.exp, lambda a: _sp().exp(a), 3, "exp a"),
    Operator("tanh", 23, 1, np.tanh, lambda a: _sp().tanh(a), 3, "tanh a"),
)

_BY_NAME = {op.name: op for op in OPERATORS}
_BY_CODE = {op.code: op for op in OPERATORS}

#: The paper's function set (Table I).
DEFAULT_FUNCTIONS = ("add", "sub", "mul", "square", "cube", "sin", "cos")
#: The head block builds derived constants with these (division protected by a proxy constant).
HEAD_OPERATORS = ("add", "sub", "mul", "neg", "div", "square", "sqrtabs")


def by_name(name: str) -> Operator:
    return _BY_NAME[name]


def by_code(code: int) -> Operator:
    return _BY_CODE[code]


def names() -> tuple[str, ...]:
    return tuple(_BY_NAME)
