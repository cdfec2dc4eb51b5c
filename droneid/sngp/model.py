"""A fitted symbolic model: sympy terms + coefficients, JSON round trip, numpy prediction.

Notation of ``equation``: the sum of ``coef*term`` with coefficients to 4 significant figures,
then the intercept. A prior feature appears as a symbol ``P<i>`` or ``P<i>_<name>`` (e.g.
``0.9981*P1_gravity_x``), defined in ``priors`` (symbol -> expression over the inputs). Evolved
features are written with the signal names; ``abs``, ``sqrt``, ``sin``, ... as in
:mod:`droneid.core.expressions`, so saved terms are read back by the same safe parser.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from droneid.errors import ConfigError, DataError, MissingSignalError
from droneid.core.expressions import compile_expression, parse_expression, round_expr, symbol, to_text

__all__ = ["SymbolicModel", "to_text", "round_expr"]

FORMAT = "droneid.sngp/1"


@dataclass
class SymbolicModel:
    """``f = intercept + sum(coef_i * term_i)``; terms over input symbols and prior symbols."""
    input_names: tuple[str, ...]
    terms: list                      # sympy expressions (raw, exactly what the engine evaluated)
    coefs: list                      # floats
    intercept: float
    priors: dict = field(default_factory=dict)   # prior symbol name -> sympy expr over inputs
    prior_labels: dict = field(default_factory=dict)  # prior symbol name -> user's prior name
    target_name: str = "y"

    def expression(self, expand_priors: bool = True) -> sp.Expr:
        e = sp.Float(self.intercept) + sum((sp.Float(c) * t for c, t in zip(self.coefs, self.terms)),
                                           sp.Integer(0))
        if expand_priors and self.priors:
            e = e.xreplace({symbol(k): v for k, v in self.priors.items()})
        return e

    def predict(self, columns) -> np.ndarray:
        """Evaluate on a mapping name -> (n,) array, or an (n, d) array in ``input_names`` order."""
        cols = self._columns(columns)
        n = len(next(iter(cols.values()))) if cols else 0
        out = np.full(n, float(self.intercept))
        env = dict(cols)
        for name, expr in self.priors.items():
            env[name] = compile_expression(expr, self.input_names)(cols)
        names = list(self.input_names) + list(self.priors)
        for c, t in zip(self.coefs, self.terms):
            with np.errstate(all="ignore"):
                out = out + float(c) * compile_expression(t, names)(env)
        return out

    def _columns(self, columns) -> dict:
        if isinstance(columns, Mapping):
            missing = [n for n in self.input_names if n not in columns]
            if missing:
                raise MissingSignalError(missing[0], list(columns), where="the data to predict on")
            return {n: np.asarray(columns[n], dtype=float) for n in self.input_names}
        X = np.asarray(columns, dtype=float)
        if X.ndim != 2 or X.shape[1] != len(self.input_names):
            raise DataError(f"X must be (n, {len(self.input_names)}) with columns "
                            f"{list(self.input_names)}, got shape {X.shape}")
        return {n: X[:, i] for i, n in enumerate(self.input_names)}

    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "target": self.target_name,
            "inputs": list(self.input_names),
            "intercept": float(self.intercept),
            "terms": [{"expr": to_text(t), "coef": float(c)} for c, t in zip(self.coefs, self.terms)],
            "priors": [{"symbol": k, "name": self.prior_labels.get(k, k), "expr": to_text(v)}
                       for k, v in self.priors.items()],
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> "SymbolicModel":
        if not isinstance(d, Mapping) or d.get("format") != FORMAT:
            raise ConfigError(f"not a saved droneid SNGP model (expected format {FORMAT!r})")
        try:
            inputs = tuple(d["inputs"])
            priors = {p["symbol"]: parse_expression(p["expr"], inputs, what=f"prior {p['symbol']}")
                      for p in d.get("priors", [])}
            labels = {p["symbol"]: p.get("name", p["symbol"]) for p in d.get("priors", [])}
            names = list(inputs) + list(priors)
            terms = [parse_expression(t["expr"], names, what="model term") for t in d["terms"]]
            coefs = [float(t["coef"]) for t in d["terms"]]
            return cls(inputs, terms, coefs, float(d["intercept"]), priors, labels,
                       d.get("target", "y"))
        except (KeyError, TypeError) as exc:
            raise ConfigError(f"saved SNGP model is incomplete: {exc}") from None
