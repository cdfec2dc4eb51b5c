"""The prior-model types: :class:`PriorFeature` (one term) and :class:`PriorModel` (an equation
per target, with its inputs, parameters, vehicle kind and constraint set).

Their own module so that the built-in models (:mod:`priors.registry`) and the TOML loader
(:mod:`priors.user`) both build on them without importing each other in a circle.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import sympy as sp

from droneid.errors import ConfigError, DataError, MissingSignalError, did_you_mean
from droneid.core.expressions import compile_expression

from . import constraints as pc

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
    (:data:`ROLE_BOUNDS`). ``magnitude``: for a ``thrust`` term, the specific thrust it stands
    for without its direction (m/s² at coefficient 1), so a fit can be checked for positive
    thrust whatever the prior."""
    name: str
    expr: sp.Expr
    description: str = ""
    role: str = "other"
    limits: tuple[float, float] | None = None
    magnitude: sp.Expr | None = None

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
    constraints : its constraint set: a built-in set's name (:func:`priors.registry.get_constraints`),
        the path of a constraints TOML, or a callable ``(prior, target, columns) -> (ConstraintSet,
        levels)`` that builds the set from the training data (``columns``: signal -> array;
        ``levels``: the domains of further inputs where drag-sign constraints are added, e.g.
        the thrust inputs' span); see :meth:`constraint_set`
    intercept : mapping target -> (low, high) of the free constant a refit may add (m/s² for
        v̇); missing targets: free. ``(0, 0)``: none (a model whose constant is known physics,
        e.g. free fall at zero thrust)
    hover_param : the parameter hover balance sets from the data (the nominal thrust scale, e.g.
        ``k_T``; see :meth:`hover_calibrated`), or None for a prior without logged thrust
    factory : the function that builds this prior from its ``params`` (its catalogue entry), so a
        stage can change one parameter (:meth:`with_params`); None: the prior is fixed
    rotational : the name of the prior modelling the same vehicle's rotation (ω̇), or None
    """
    name: str
    description: str
    terms: Mapping[str, tuple[PriorFeature, ...]]
    input_names: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    params: Mapping[str, float] = field(default_factory=dict)
    vehicle: str = "any"
    constraints: str | Callable = "paper"
    intercept: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    hover_param: str | None = None
    factory: Callable | None = field(default=None, compare=False, repr=False)
    rotational: str | None = None

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

    def with_params(self, **params) -> "PriorModel":
        """The same prior built with some parameters changed (ConfigError for a fixed prior)."""
        if self.factory is None:
            raise ConfigError(f"prior '{self.name}' is fixed: its parameters cannot be changed")
        return self.factory(**{**dict(self.params), **params})

    def thrust_signals(self, target: str) -> list[str]:
        """The logged signals the thrust terms of ``target`` read (motor speeds, commands,
        thrust), not the attitude that only turns them nor the battery voltage that scales a
        command; [] for a prior without thrust terms."""
        return sorted({s for f in self.features(target) if f.role == "thrust" for s in f.signals
                       if s not in ("roll", "pitch", "yaw", "battery_voltage")})

    def hover_calibrated(self, columns: Mapping[str, np.ndarray], target: str = "vz_dot") -> "PriorModel":
        """This prior with its :attr:`hover_param` set by hover balance on data (``columns``: the
        training rows' inputs of ``target``): the median of the thrust terms of ``target`` is g,
        so the fitted scales read as ~1 and the 1-feature form is a sensible model as given. Uses
        inputs only, never a measured derivative. Unchanged without a hover parameter, thrust
        terms or positive thrust."""
        if self.hover_param is None or target not in self.terms:
            return self
        feats = self.features(target)
        if not any(f.role == "thrust" for f in feats) or not len(next(iter(columns.values()), ())):
            return self
        values = self.evaluate(columns, target)
        lift = sum(values[:, i] for i, f in enumerate(feats) if f.role == "thrust")
        med = float(np.median(lift)) / float(self.params[self.hover_param])
        if not med > 0:
            return self
        return self.with_params(**{self.hover_param: float(self.params.get("g", 9.81)) / med})

    def fitted_thrust(self, target: str, coefficients: Mapping[str, float],
                      columns: Mapping[str, np.ndarray], n: int) -> np.ndarray | None:
        """The specific thrust (m/s², without direction) of a fit of ``target`` on data: the thrust
        terms' :attr:`PriorFeature.magnitude` times their fitted coefficients (``coefficients``
        keyed by feature name), or None for a prior without thrust magnitudes."""
        feats = [f for f in self.features(target) if f.role == "thrust" and f.magnitude is not None]
        if not feats:
            return None
        out = np.zeros(n)
        for f in feats:
            names = sorted(s.name for s in f.magnitude.free_symbols)
            out = out + float(coefficients.get(f.name, 0.0)) * compile_expression(f.magnitude, names)(
                {k: columns[k] for k in names})
        return out

    def constraint_set(self, target: str, columns: Mapping[str, np.ndarray] | None = None):
        """(ConstraintSet, levels, data_built) this prior declares for ``target``: a set built
        from the training data (a callable ``constraints``; ``levels`` are the domains of
        further inputs for added drag-sign constraints), its constraints TOML, or a built-in set
        (``levels`` empty). Raises ConfigError when the prior declares none for ``target``."""
        if callable(self.constraints):
            if columns is None:
                raise ConfigError(f"prior '{self.name}' builds its constraints from data: none given")
            cs, levels = self.constraints(self, target, columns)
            return cs, dict(levels), True
        if str(self.constraints).endswith(".toml"):
            return pc.load_constraints(self.constraints, target=target), {}, False
        return pc.constraint_set(self.constraints, self.name, target), {}, False

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
