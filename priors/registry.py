"""Prior models: empirical equations given to SNGP as prior features.

A :class:`PriorModel` holds, per target, the terms of an equation as sympy expressions over the
signal symbols of :func:`droneid.core.expressions.symbol`. ``features(target, 1)`` is the whole
equation as one prior feature; ``features(target)`` (or ``n_features`` = the number of terms) is
one prior feature per term, so least squares weighs each term separately (the paper's "3 priors").

Built-in models (:func:`get_prior`, :data:`PRIORS`): one module each in
:mod:`priors.prior_catalogue` (``tilt-drag``, the paper's drone model; ``rotor-thrust``, thrust
from the logged motor speeds / commands / thrust along the body z axis; ``unicycle``, the paper's
TurtleBot); their docstrings give the equations. ``auto`` picks one from the log's signals
(:func:`choose_prior`).

User priors come from TOML files (:func:`load_priors`, see :mod:`priors.user`).
"""
from __future__ import annotations

import re

import inspect
from types import MappingProxyType

from droneid.errors import ConfigError, did_you_mean
from droneid.core.plugins import public_modules

from . import constraints as pc
from .base import ROLES, PriorFeature, PriorModel
from .prior_catalogue.rotor_thrust import rotor_thrust
from .prior_catalogue.tilt_drag import tilt_drag
from .prior_catalogue.unicycle import unicycle
from .thrust import THRUST_SOURCES, motor_count
from .user import load_priors

__all__ = ["PriorFeature", "PriorModel", "PRIORS", "ROLES", "get_prior", "load_priors", "tilt_drag",
           "rotor_thrust", "unicycle", "resolve_prior", "is_prior_spec", "choose_prior", "prior_for",
           "get_constraints"]


def choose_prior(signals, requested: str = "auto", slow=None) -> tuple[str, dict, str]:
    """(prior name, its parameters, the reason) for ``requested`` on data with these signals.

    ``auto``: the most physical prior the signals support: rotor-thrust from motor speeds, else
    motor commands, else collective thrust, else the collective command; tilt-drag otherwise.
    A motor source counts only with at least 3 motors (a multirotor's worth). ``slow``
    ({signal: rate in Hz}) are signals the data have, but too slowly for the fit: when a thrust
    source is among them, the reason says so instead of "no motor ...".
    """
    have = set(signals)
    counts = motor_count(have)
    if requested not in ("auto", "rotor-thrust"):
        return requested, {}, "named by the user"
    passed = []         # per-motor sources with a motor missing: said, never silently skipped
    for src in THRUST_SOURCES:
        present = sorted(int(m.group(1)) for n in have if (m := re.fullmatch(rf"{src}(\d+)", str(n))))
        gap = bool(present) and present[-1] != len(present)
        if src in counts and counts[src] >= 3 and not gap:
            return "rotor-thrust", {"source": src, "motors": counts[src]}, (
                f"the log has {counts[src]} {_WHAT[src]} ({src}1..{src}{counts[src]})" + _incomplete(passed))
        if src in ("thrust", "throttle") and src in have:
            return "rotor-thrust", {"source": src}, f"the log has the collective {src}" + _incomplete(passed)
        if gap and src in ("rpm", "motor"):
            missing = next(i for i in range(1, present[-1] + 1) if i not in present)
            passed.append(f"its {_WHAT[src]} are incomplete ({', '.join(f'{src}{i}' for i in present)}; "
                          f"no {src}{missing})")
    too_slow = _slow_thrust(slow or {})
    if requested == "rotor-thrust":
        raise ConfigError("prior 'rotor-thrust' needs motor speeds (rpm1..), motor commands "
                          "(motor1..), collective thrust or throttle; "
                          + (too_slow or ("the data have no complete set of them" if passed else
                                          "the data have none of them")) + _incomplete(passed))
    return "tilt-drag", {}, (too_slow or ("the log has no complete set of motor speeds or motor commands, and no thrust"
                                          if passed else "the log has no motor speeds, motor commands or thrust")
                             ) + _incomplete(passed)


def _incomplete(passed) -> str:
    """"; its motor speeds are incomplete (rpm1, rpm2, rpm4; no rpm3)" for the per-motor sources
    the choice passed over because a motor is missing ("" for none)."""
    return "".join(f"; {p}" for p in passed)


#: the thrust sources of :data:`THRUST_SOURCES` in words
_WHAT = {"rpm": "motor speeds", "motor": "motor commands", "thrust": "collective thrust",
         "throttle": "collective command (throttle)"}


def _slow_thrust(slow) -> str:
    """"the log's motor commands (motor1..motor4) come at 1.0 Hz only, ..." for the first thrust
    source (in :data:`THRUST_SOURCES` order) among signals logged too slowly; "" for none."""
    counts = motor_count(slow)
    for src, (pattern, _, _) in THRUST_SOURCES.items():
        per_motor = "{i}" in pattern
        names = ([pattern.format(i=i) for i in range(1, counts.get(src, 0) + 1)] if per_motor
                 else [pattern] if pattern in slow else [])
        if len(names) >= (3 if per_motor else 1):
            what = f"{_WHAT[src]} ({names[0]}..{names[-1]}) come" if per_motor else f"{_WHAT[src]} comes"
            return (f"the log's {what} at {min(slow[n] for n in names):.1f} Hz only, too slow for a "
                    f"fit at this sampling period (--ts)")
    return ""


def _discover() -> dict:
    """{name: factory} of every module of :mod:`priors.prior_catalogue`, in ``ORDER``."""
    found = []
    for mod in public_modules("priors.prior_catalogue"):
        name, order, factory = (getattr(mod, k, None) for k in ("NAME", "ORDER", "FACTORY"))
        if not (isinstance(name, str) and isinstance(order, int) and callable(factory)):
            raise ConfigError(f"{getattr(mod, '__file__', mod.__name__)}: a module of priors.prior_catalogue "
                              f"must export NAME (str), ORDER (int) and FACTORY (callable)")
        found.append((order, name, factory))
    names = [n for _, n, _ in found]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup:
        raise ConfigError(f"prior {dup!r} is defined twice in priors.prior_catalogue")
    return {n: f for _, n, f in sorted(found, key=lambda x: (x[0], x[1]))}


#: name -> factory(**params) -> PriorModel, the built-in priors (one module each)
PRIORS = MappingProxyType(_discover())


def get_prior(name: str, **params) -> PriorModel:
    """A built-in prior model by name, with its parameters (e.g. ``get_prior("tilt-drag", k_D=0.3)``)."""
    if name not in PRIORS:
        raise ConfigError(f"unknown prior {name!r}{did_you_mean(str(name), PRIORS)}; "
                          f"built-in priors: {', '.join(PRIORS)} (a prior of your own: --prior FILE.toml:NAME, or "
                          f"priors.registry.load_priors(path) in Python)")
    accepted = list(inspect.signature(PRIORS[name]).parameters)
    for k in params:
        if k not in accepted:
            raise ConfigError(f"prior '{name}' has no parameter {k!r}{did_you_mean(k, accepted)}; "
                              f"its parameters: {', '.join(accepted) or 'none'}")
    return PRIORS[name](**params)


def prior_for(spec: str | PriorModel, signals, slow=None) -> tuple[PriorModel, str]:
    """(PriorModel, why) for ``spec`` on data with these ``signals``: ``auto`` (and a bare
    ``rotor-thrust``) choose with :func:`choose_prior` (``slow``: signals present but too slow);
    anything else is :func:`resolve_prior`. The one place identify, diagnose and the CLI turn
    ``--prior`` into a model (through :func:`droneid.dataset.suitability.prior_for_flights`)."""
    if isinstance(spec, str) and spec in ("auto", "rotor-thrust"):
        name, params, why = choose_prior(signals, spec, slow)
        return get_prior(name, **params), why
    return resolve_prior(spec), "named by the user"


def is_prior_spec(spec) -> bool:
    """Whether ``spec`` names a prior model (a built-in name or ``FILE.toml:NAME``) rather than,
    say, an expression."""
    return isinstance(spec, str) and (spec in PRIORS or _toml_spec(spec) is not None)


def _toml_spec(spec: str) -> tuple[str, str] | None:
    """(path, name) of ``FILE.toml:NAME``, else None."""
    path, sep, name = spec.partition(":")
    return (path, name) if sep and path.endswith(".toml") else None


def resolve_prior(spec: str | PriorModel, **params) -> PriorModel:
    """A PriorModel from a built-in name or ``file.toml:name``."""
    if isinstance(spec, PriorModel) or (not isinstance(spec, str) and hasattr(spec, "features")):
        return spec  # a PriorModel, or an object that behaves as one (features, inputs, targets)
    if not isinstance(spec, str):
        raise ConfigError(f"a prior must be a name, FILE.toml:NAME or a PriorModel; got {type(spec).__name__}")
    if _toml_spec(spec) is not None:
        path, name = _toml_spec(spec)
        models = load_priors(path)
        if name not in models:
            raise ConfigError(f"{path}: no prior {name!r}{did_you_mean(name, models)}; "
                              f"it defines {', '.join(models) or 'none'}")
        return models[name]
    return get_prior(spec, **params)


def _priors_with(name: str, target: str) -> list[str]:
    """The built-in priors that declare constraint set ``name`` and model ``target``."""
    return [prior for prior in pc.CONSTRAINT_SETS.get(name, {})
            if PRIORS[prior]().constraints == name and target in PRIORS[prior]().targets]


def get_constraints(name: str = "paper", target: str = "vx_dot", prior: str | None = None
                    ) -> pc.ConstraintSet:
    """A built-in constraint set. ``prior`` picks the vehicle (``tilt-drag``: the paper's drone,
    ``unicycle``: its TurtleBot); by default it follows from the target."""
    if prior is None and name in pc.CONSTRAINT_SETS:
        found = _priors_with(name, target)
        if not found:
            known = sorted({t for p in pc.CONSTRAINT_SETS[name] for t in PRIORS[p]().targets})
            raise ConfigError(f"constraint set {name!r} has no constraints for {target!r}; targets: "
                              f"{', '.join(known)}")
        prior = found[0]
    return pc.constraint_set(name, prior, target)
