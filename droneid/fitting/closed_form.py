"""The model ``droneid identify`` hands the user, per target, as one closed-form expression.

An :class:`IdentifiedModel` is the FINAL model of one target: the prior's terms with their fitted
scales, the effects the diagnosis added (with their fitted constants) and the evolved terms that
survived validation, summed into one sympy expression over canonical signal names (see
:data:`droneid.logs.flight.CANONICAL_SIGNALS`). ``delays_s`` says which input signals enter delayed:
signal ``s`` is read at ``t − delays_s[s]`` (e.g. motor speeds logged ahead of their effect).

It is what ``predict`` evaluates, what multi-step prediction integrates and what ``export``
prints; ``result.json`` stores it under ``targets.<target>.final`` (``to_dict``).
"""
from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType

import numpy as np
import sympy as sp

from droneid.errors import DataError, MissingSignalError
from droneid.core.expressions import compile_expression, parse_expression, round_expr, to_text

__all__ = ["IdentifiedModel", "SCHEMA", "check_schema"]

#: the ``schema`` of identify's result.json (docs/result-json.md); version 1, from before the typed
#: results, is refused by everything that reads a result
SCHEMA = "droneid.identify/2"

# sympy's printed names -> the names the safe parser accepts
_PRINTED = {"Abs": "abs", "Min": "min", "Max": "max"}


@dataclass(frozen=True)
class IdentifiedModel:
    """target : e.g. ``"vx_dot"``; expr : sympy expression over signal symbols (m/s² for v̇);
    delays_s : {signal: delay in s}; description : what the model is made of (one line);
    unit : unit of the target."""
    target: str
    expr: sp.Expr
    delays_s: Mapping[str, float] = field(default_factory=dict)
    description: str = ""
    unit: str = "m/s^2"

    def __post_init__(self):
        object.__setattr__(self, "delays_s", MappingProxyType(
            {str(k): float(v) for k, v in dict(self.delays_s).items() if float(v) != 0.0}))

    @property
    def signals(self) -> tuple[str, ...]:
        """The signals the expression reads, sorted."""
        return tuple(sorted(s.name for s in self.expr.free_symbols))

    def evaluate(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        """The model on data: ``columns`` maps signal names to (n,) arrays, already delayed as
        ``delays_s`` says (``DatasetBuilder(delays_s=...)`` does that). Returns (n,) floats."""
        missing = [s for s in self.signals if s not in columns]
        if missing:
            raise MissingSignalError(missing[0], list(columns), where=f"the data for the {self.target} model")
        n = len(next(iter(columns.values()))) if columns else 0
        f = self._compiled
        return np.broadcast_to(np.asarray(f({s: np.asarray(columns[s], float) for s in self.signals})
                                          if self.signals else float(self.expr), float), (n,)).copy()

    @cached_property
    def _compiled(self):
        """The expression compiled once (numpy); evaluate() is called per RK4 stage in rollouts."""
        return compile_expression(self.expr, self.signals)

    def text(self, sig: int = 4) -> str:
        """The expression with numbers to ``sig`` significant figures."""
        return to_text(round_expr(self.expr, sig))

    def to_dict(self) -> dict:
        return {"target": self.target, "expr": sp.sstr(self.expr, full_prec=True),
                "signals": list(self.signals), "delays_s": dict(self.delays_s),
                "description": self.description, "unit": self.unit, "equation": f"{self.target} = {self.text()}"}

    @classmethod
    def from_dict(cls, d: Mapping) -> "IdentifiedModel":
        """Read back ``to_dict()`` (the expression is parsed safely, never eval'ed)."""
        try:
            text = str(d["expr"])
            signals = list(d.get("signals") or [])
            target = str(d["target"])
        except (KeyError, TypeError) as exc:
            raise DataError(f"not an identified model: missing {exc}") from None
        for a, b in _PRINTED.items():
            text = re.sub(rf"\b{a}\(", f"{b}(", text)
        expr = parse_expression(text, signals, what=f"identified model of {target}")
        return cls(target, expr, dict(d.get("delays_s") or {}), str(d.get("description", "")),
                   str(d.get("unit", "m/s^2")))


def check_schema(d: Mapping, where: str = "the result") -> None:
    """DataError in one line unless ``d`` is a result.json of :data:`SCHEMA`."""
    schema = d.get("schema") if isinstance(d, Mapping) else None
    if schema == SCHEMA:
        return
    if schema == "droneid.identify/1":
        raise DataError(f"{where} was made by an older droneid (schema {schema}); re-run "
                        f"`droneid identify` to make a {SCHEMA} result")
    raise DataError(f"{where} is not a droneid identification result (schema {schema!r}, expected {SCHEMA!r})")
