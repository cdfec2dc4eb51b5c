"""The prior-model types: :class:`PriorFeature` (one term) and :class:`PriorModel` (an equation
per target, with its inputs, parameters, vehicle kind and constraint set).

Their own module so that the built-in models (:mod:`priors.models`) and the TOML loader
(:mod:`priors.user`) both build on them without importing each other in a circle.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import sympy as sp

from droneid.errors import ConfigError, DataError, MissingSignalError, did_you_mean
from droneid.expressions import compile_expression

__all__ = ["PriorFeature", "PriorModel", "ROLES", "ROLE_BOUNDS", "VEHICLE_KINDS", "check_param"]

#: what a prior's ``vehicle`` may say (the data-fitness check knows multirotor and fixed-wing)
VEHICLE_KINDS = ("multirotor", "fixed-wing", "ground", "any")


#: values beyond this are treated as non-finite (as the SNGP engine does: tan near ±90°)
_MAX_ABS = 1e12


#: What a prior term stands for physically; effects and the identify pipeline read it.
ROLES = ("tilt", "thrust", "drag", "gravity", "kinematic", "other")

#: The physical range of a term's fitted coefficient, by role. Every prior term is written at its
#: nominal scale, so the coefficient is a relative scale (1 = nominal): a thrust or tilt (thrust
#: direction) scale is positive, a drag term (written as −k v) has a coefficient >= 0 (drag never
#: pushes), gravity is known physics (fixed at 1, never fitted); other terms are free. A feature's
#: own ``bounds`` override its role's.
ROLE_BOUNDS = MappingProxyType({
    "tilt": (0.0, np.inf), "thrust": (0.0, np.inf), "drag": (0.0, np.inf), "gravity": (1.0, 1.0),
    "kinematic": (-np.inf, np.inf), "other": (-np.inf, np.inf)})


@dataclass(frozen=True)
class PriorFeature:
    """One prior feature: ``name`` (an identifier), ``expr`` (sympy over signal symbols),
    ``description`` (what it means) and ``role`` (one of :data:`ROLES`: ``tilt`` = the thrust
    direction at hover balance (tilt-drag), ``thrust`` = logged thrust along the body z axis,
    ``drag``, ``gravity`` (a constant), ``kinematic``, ``other``). ``limits``: the physical
    (low, high) range of its fitted coefficient when it differs from its role's
    (:data:`ROLE_BOUNDS`)."""
    name: str
    expr: sp.Expr
    description: str = ""
    role: str = "other"
    limits: tuple[float, float] | None = None

    @property
    def bounds(self) -> tuple[float, float]:
        """The physical (low, high) range of this term's fitted coefficient (low == high: fixed)."""
        return tuple(self.limits) if self.limits is not None else ROLE_BOUNDS.get(self.role, (-np.inf, np.inf))

    @property
    def signals(self) -> tuple[str, ...]:
        """The signal names the expression uses, sorted."""
        return tuple(sorted(s.name for s in self.expr.free_symbols))


@dataclass(frozen=True)
class PriorModel:
    """A named prior model.

    terms : mapping target -> tuple of :class:`PriorFeature` (the equation's terms, summed)
    input_names : mapping target -> the inputs a model of that target is given (paper's choice)
    params : the parameters the terms were built with (numbers; a rotor-thrust source name)
    vehicle : the kind of vehicle the model describes, one of :data:`VEHICLE_KINDS`
    constraints : its constraint set: a built-in set's name (:func:`priors.constraints.get_constraints`,
        ``rotor-thrust``: built from the data's thrust span) or the path of a constraints TOML
    intercept : mapping target -> (low, high) of the free constant a refit may add (m/s² for
        v̇); missing targets: free. ``(0, 0)``: none (a model whose constant is known physics,
        e.g. free fall at zero thrust)
    """
    name: str
    description: str
    terms: Mapping[str, tuple[PriorFeature, ...]]
    input_names: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    params: Mapping[str, float] = field(default_factory=dict)
    vehicle: str = "any"
    constraints: str = "paper"
    intercept: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "terms", MappingProxyType({k: tuple(v) for k, v in self.terms.items()}))
        object.__setattr__(self, "input_names",
                           MappingProxyType({k: tuple(v) for k, v in self.input_names.items()}))
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))
        object.__setattr__(self, "intercept", MappingProxyType({k: tuple(v) for k, v in self.intercept.items()}))

    def intercept_bounds(self, target: str) -> tuple[float, float]:
        """(low, high) of the constant a refit of ``target`` may add."""
        return tuple(self.intercept.get(target, (-np.inf, np.inf)))

    def offset(self, target: str) -> sp.Expr:
        """The known physics of ``target`` that no fit touches: the sum of its constant terms
        whose coefficient is fixed (gravity); 0 when there are none."""
        return sp.Add(*[t.expr for t in self._terms(target)
                        if not t.expr.free_symbols and t.bounds[0] == t.bounds[1]]) * 1

    @property
    def targets(self) -> tuple[str, ...]:
        return tuple(self.terms)

    def _terms(self, target: str) -> tuple[PriorFeature, ...]:
        try:
            return self.terms[target]
        except KeyError:
            raise ConfigError(f"prior '{self.name}' has no model of {target!r}"
                              f"{did_you_mean(str(target), self.terms)}; it models "
                              f"{', '.join(self.terms)}") from None

    def features(self, target: str, n_features: int | None = None) -> tuple[PriorFeature, ...]:
        """The prior features for ``target``: one per term (``n_features`` None or the number of
        terms), or the whole equation as one feature (``n_features=1``)."""
        terms = self._terms(target)
        if n_features is None or n_features == len(terms):
            return terms
        if n_features == 1:
            desc = f"{self.name} model of {target}: " + " + ".join(t.name for t in terms)
            return (PriorFeature(f"{self.name.replace('-', '_')}_{target}",
                                 sp.Add(*[t.expr for t in terms]), desc),)
        raise ConfigError(f"The 'n_features' parameter of prior '{self.name}' for {target} must be "
                          f"1 or {len(terms)}. Got {n_features!r} instead.")

    def inputs(self, target: str) -> tuple[str, ...]:
        """The inputs a model of ``target`` gets (the paper's; otherwise the signals the
        prior uses)."""
        terms = self._terms(target)
        if target in self.input_names:
            return self.input_names[target]
        return tuple(sorted({s for t in terms for s in t.signals}))

    def signals(self, target: str) -> tuple[str, ...]:
        """The signals the prior's expressions for ``target`` use."""
        return tuple(sorted({s for t in self._terms(target) for s in t.signals}))

    def evaluate(self, columns: Mapping[str, np.ndarray], target: str,
                 n_features: int | None = None) -> np.ndarray:
        """The prior features on data: an (n, k) array, one column per feature.

        ``columns`` maps signal names to (n,) arrays (e.g. ``Dataset.columns()``; a ``t``
        column, when present, is used to say where values are bad). Raises
        :class:`MissingSignalError` naming the prior and the signal when a column is missing,
        and :class:`DataError` with the count and location of non-finite values (tan near ±90°).
        """
        feats = self.features(target, n_features)
        lengths = {len(np.asarray(v)) for v in columns.values()}
        if len(lengths) > 1:
            raise DataError(f"prior '{self.name}': columns of different lengths {sorted(lengths)}")
        n = lengths.pop() if lengths else 0
        for s in self.signals(target):
            if s not in columns:
                raise MissingSignalError(s, [k for k in columns if k != "t"],
                                         where=f"the data given to prior '{self.name}' ({target})")
        out = np.empty((n, len(feats)))
        for j, f in enumerate(feats):
            names = f.signals
            out[:, j] = compile_expression(f.expr, names)({k: columns[k] for k in names}) \
                if n else np.empty(0)
            with np.errstate(invalid="ignore"):
                bad = ~(np.abs(out[:, j]) <= _MAX_ABS)  # also catches nan
            if bad.any():
                idx = np.flatnonzero(bad)
                where = f"sample {idx[0]}"
                if "t" in columns:
                    tt = np.asarray(columns["t"], dtype=float)
                    where = f"t = {tt[idx[0]]:.3f} s"
                    if idx.size > 1:
                        where += f" .. {tt[idx[-1]]:.3f} s"
                raise DataError(f"prior '{self.name}' feature '{f.name}' is non-finite (or beyond "
                                f"±{_MAX_ABS:g}) on "
                                f"{idx.size} of {n} samples (first at {where}); e.g. tan near "
                                f"±90° or division by zero: trim those samples")
        return out


# -- built-in models ----------------------------------------------------------------------------


def check_param(prior: str, name: str, value) -> float:
    """``value`` as a float; ConfigError naming the prior and the parameter unless it is a finite
    number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ConfigError(f"The '{name}' parameter of prior '{prior}' must be a finite number. "
                          f"Got {value!r} instead.")
    return float(value)
