"""Prior models: empirical equations given to SNGP as prior features.

A :class:`PriorModel` holds, per target, the terms of an equation as sympy expressions over the
signal symbols of :func:`droneid.expressions.symbol`. ``features(target, 1)`` is the whole
equation as one prior feature; ``features(target)`` (or ``n_features`` = the number of terms) is
one prior feature per term, so least squares weighs each term separately (the paper's "3 priors").

Built-in models (:func:`get_prior`):

``tilt-drag`` (params ``g`` = 9.81 m/s², ``k_D`` = 0.28 1/s), the paper's eqs. 18-19 in droneid's
angles (φ roll, θ pitch, ψ yaw; see :mod:`droneid.frames`)::

    vx_dot = g cosψ tanθ / cosφ + g sinψ tanφ − k_D vx
    vy_dot = g sinψ tanθ / cosφ − g cosψ tanφ − k_D vy

``unicycle`` (the paper's TurtleBot 2), targets ``x_dot`` and ``y_dot``::

    x_dot = v_f cos(yaw),  y_dot = v_f sin(yaw)

with the heading φ as the canonical ``yaw`` (counter-clockwise from the world x axis) and the
non-canonical command signals ``v_f`` (forward velocity command, m/s) and ``v_a`` (angular
velocity command, rad/s; an input of the paper's TurtleBot models but not of the prior).

User priors come from TOML files (:func:`load_priors`, see :mod:`priors.user`).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import sympy as sp

from droneid.errors import ConfigError, DataError, MissingSignalError, did_you_mean
from droneid.expressions import compile_expression, symbol

__all__ = ["PriorFeature", "PriorModel", "PRIORS", "get_prior", "load_priors", "tilt_drag",
           "unicycle", "resolve_prior"]


#: values beyond this are treated as non-finite (as the SNGP engine does: tan near ±90°)
_MAX_ABS = 1e12


@dataclass(frozen=True)
class PriorFeature:
    """One prior feature: ``name`` (an identifier), ``expr`` (sympy over signal symbols),
    ``description`` (what it means)."""
    name: str
    expr: sp.Expr
    description: str = ""

    @property
    def signals(self) -> tuple[str, ...]:
        """The signal names the expression uses, sorted."""
        return tuple(sorted(s.name for s in self.expr.free_symbols))


@dataclass(frozen=True)
class PriorModel:
    """A named prior model.

    terms : mapping target -> tuple of :class:`PriorFeature` (the equation's terms, summed)
    input_names : mapping target -> the inputs a model of that target is given (paper's choice)
    params : the numeric parameters the terms were built with
    """
    name: str
    description: str
    terms: Mapping[str, tuple[PriorFeature, ...]]
    input_names: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    params: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "terms", MappingProxyType({k: tuple(v) for k, v in self.terms.items()}))
        object.__setattr__(self, "input_names",
                           MappingProxyType({k: tuple(v) for k, v in self.input_names.items()}))
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))

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
def tilt_drag(g: float = 9.81, k_D: float = 0.28) -> PriorModel:
    """The paper's empirical drone model (eqs. 18-19): thrust tilt in the world frame plus
    linear drag, in droneid's angles (roll φ, pitch θ positive nose down, yaw ψ CCW from east)."""
    g, k_D = _check_param("tilt-drag", "g", g), _check_param("tilt-drag", "k_D", k_D)
    vx, vy, phi, theta, psi = (symbol(n) for n in ("vx", "vy", "roll", "pitch", "yaw"))
    G, K = sp.Float(g), sp.Float(k_D)
    terms = {
        "vx_dot": (
            PriorFeature("g_cos_yaw_tan_pitch_over_cos_roll", G * sp.cos(psi) * sp.tan(theta) / sp.cos(phi),
                         "forward tilt (pitch) thrust component along world x"),
            PriorFeature("g_sin_yaw_tan_roll", G * sp.sin(psi) * sp.tan(phi),
                         "sideways tilt (roll) thrust component along world x"),
            PriorFeature("minus_kD_vx", -K * vx, "linear drag along world x"),
        ),
        "vy_dot": (
            PriorFeature("g_sin_yaw_tan_pitch_over_cos_roll", G * sp.sin(psi) * sp.tan(theta) / sp.cos(phi),
                         "forward tilt (pitch) thrust component along world y"),
            PriorFeature("minus_g_cos_yaw_tan_roll", -G * sp.cos(psi) * sp.tan(phi),
                         "sideways tilt (roll) thrust component along world y"),
            PriorFeature("minus_kD_vy", -K * vy, "linear drag along world y"),
        ),
    }
    return PriorModel(
        "tilt-drag",
        "Empirical quadrotor model of the paper (eqs. 18-19): horizontal acceleration from the "
        "tilted thrust at hover balance plus linear drag -k_D v.",
        terms,
        {"vx_dot": ("vx", "pitch", "roll", "yaw"), "vy_dot": ("vy", "pitch", "roll", "yaw")},
        {"g": g, "k_D": k_D},
    )


def unicycle() -> PriorModel:
    """The paper's TurtleBot prior: x_dot = v_f cos(yaw), y_dot = v_f sin(yaw)."""
    v_f, yaw = symbol("v_f"), symbol("yaw")
    inputs = ("x", "y", "yaw", "v_f", "v_a")
    return PriorModel(
        "unicycle",
        "Kinematic unicycle (the paper's TurtleBot 2 prior): the robot moves along its heading "
        "yaw at the commanded forward velocity v_f.",
        {"x_dot": (PriorFeature("v_f_cos_yaw", v_f * sp.cos(yaw), "commanded velocity along world x"),),
         "y_dot": (PriorFeature("v_f_sin_yaw", v_f * sp.sin(yaw), "commanded velocity along world y"),)},
        {"x_dot": inputs, "y_dot": inputs},
    )


def _check_param(prior: str, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ConfigError(f"The '{name}' parameter of prior '{prior}' must be a finite number. "
                          f"Got {value!r} instead.")
    return float(value)


#: name -> factory(**params) -> PriorModel
PRIORS = {"tilt-drag": tilt_drag, "unicycle": unicycle}


def get_prior(name: str, **params) -> PriorModel:
    """A built-in prior model by name, with its parameters (e.g. ``get_prior("tilt-drag", k_D=0.3)``)."""
    if name not in PRIORS:
        raise ConfigError(f"unknown prior {name!r}{did_you_mean(str(name), PRIORS)}; "
                          f"built-in priors: {', '.join(PRIORS)} (user priors: load_priors(path))")
    import inspect
    accepted = list(inspect.signature(PRIORS[name]).parameters)
    for k in params:
        if k not in accepted:
            raise ConfigError(f"prior '{name}' has no parameter {k!r}{did_you_mean(k, accepted)}; "
                              f"its parameters: {', '.join(accepted) or 'none'}")
    return PRIORS[name](**params)


def load_priors(path) -> dict[str, PriorModel]:
    """User prior models from a TOML file, by name (see :mod:`priors.user` for the format)."""
    from .user import load_priors as _load
    return _load(path)


def resolve_prior(spec: str | PriorModel, **params) -> PriorModel:
    """A PriorModel from a built-in name or ``file.toml:name``."""
    if isinstance(spec, PriorModel):
        return spec
    if ":" in spec and spec.split(":", 1)[0].endswith(".toml"):
        path, name = spec.split(":", 1)
        models = load_priors(path)
        if name not in models:
            raise ConfigError(f"{path}: no prior {name!r}{did_you_mean(name, models)}; "
                              f"it defines {', '.join(models) or 'none'}")
        return models[name]
    return get_prior(spec, **params)
