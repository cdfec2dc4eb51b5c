"""User prior models from TOML, parsed safely (never ``eval``).

Format (one table per prior under ``prior``)::

    [prior.mydrag]
    description = "tilt plus quadratic drag"        # optional
    target = "vx_dot"
    features = ["g*cos(yaw)*tan(pitch)/cos(roll)", "-k_D*vx*abs(vx)"]
    names = ["tilt", "quadratic_drag"]               # optional, one identifier per feature
    inputs = ["vx", "pitch", "roll", "yaw"]          # optional: the model's inputs
    signals = ["v_f"]                                # optional: non-canonical signal names used
    vehicle = "multirotor"                           # optional: multirotor, fixed-wing, ground, any
    constraints = "mydrag_constraints.toml"          # optional: its constraint set (a constraints
                                                     # TOML, relative to this file)
    [prior.mydrag.params]
    g = 9.81
    k_D = 0.3

Several targets in one prior: make ``features`` (and optionally ``names``, ``inputs``) a table
keyed by target instead of ``target`` + a list::

    [prior.tilt2.features]
    vx_dot = ["g*cos(yaw)*tan(pitch)/cos(roll)", "-k_D*vx"]
    vy_dot = ["g*sin(yaw)*tan(pitch)/cos(roll)", "-k_D*vy"]

Expressions go through :func:`droneid.core.expressions.parse_expression`: numbers, the canonical
signal names (plus those listed in ``signals``), the params, ``pi``, ``e``, ``+ - * / ** ^`` and
the whitelisted functions only. Anything else is a :class:`ConfigError` naming the file and prior.

``vehicle`` makes identify and diagnose check the logs against the prior (a multirotor prior on a
fixed-wing log is refused; ``any``, the default, skips the check). ``constraints`` is the prior's
own constraint set, used where the built-in priors use theirs (``--constraints paper``, the
default); without it a user prior's runs go unconstrained unless ``--constraints FILE`` is given.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

from droneid.core.io_util import load_toml
from droneid.errors import ConfigError, did_you_mean
from droneid.core.expressions import ALLOWED_FUNCTIONS, parse_expression
from droneid.logs.flight import CANONICAL_SIGNALS

from .base import VEHICLE_KINDS, PriorFeature, PriorModel

__all__ = ["load_priors", "priors_from_dict"]

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_KEYS = {"description", "target", "features", "names", "inputs", "signals", "params", "vehicle",
         "constraints"}

_SIGNALS = (*CANONICAL_SIGNALS, *(f"motor{i}" for i in range(1, 17)))


def load_priors(path) -> dict[str, PriorModel]:
    """Every prior defined in the TOML file at ``path``, by name."""
    path = Path(path)
    data = load_toml(path, "priors file")
    return priors_from_dict(data, where=str(path), base=path.parent)


def priors_from_dict(data: dict, where: str = "priors", base: Path | None = None) -> dict[str, PriorModel]:
    """Prior models from a parsed TOML document (``where`` names it in errors; ``base`` is the
    folder a relative ``constraints`` path is read from, default the working directory)."""
    unknown = [k for k in data if k != "prior"]
    if unknown:
        raise ConfigError(f"{where}: unknown top-level key {unknown[0]!r}; priors go in [prior.NAME] tables")
    table = data.get("prior")
    if not isinstance(table, dict) or not table:
        raise ConfigError(f"{where}: no [prior.NAME] table found")
    return {name: _one(name, spec, where, Path(base or ".")) for name, spec in table.items()}


def _one(name: str, spec, where: str, base: Path) -> PriorModel:
    ctx = f"{where}: prior '{name}'"
    if not isinstance(spec, dict):
        raise ConfigError(f"{ctx}: must be a table")
    bad = [k for k in spec if k not in _KEYS]
    if bad:
        raise ConfigError(f"{ctx}: unknown key {bad[0]!r}{did_you_mean(bad[0], _KEYS)}; "
                          f"allowed: {', '.join(sorted(_KEYS))}")
    signals = _str_list(spec.get("signals", []), f"{ctx}: signals")
    for s in signals:
        if not _IDENT.match(s):
            raise ConfigError(f"{ctx}: signal name {s!r} is not an identifier")
    allowed_signals = [*_SIGNALS, *signals]
    params = spec.get("params", {})
    if not isinstance(params, dict):
        raise ConfigError(f"{ctx}: params must be a table of numbers")
    for k, v in params.items():
        if not _IDENT.match(k) or k in ALLOWED_FUNCTIONS or k in ("pi", "e") or k in allowed_signals:
            raise ConfigError(f"{ctx}: parameter name {k!r} is not allowed (it must be an "
                              "identifier that is not a signal, function or constant name)")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{ctx}: parameter {k!r} must be a finite number, got {v!r}")
    feats = spec.get("features")
    if isinstance(feats, list):
        if "target" not in spec or not isinstance(spec["target"], str):
            raise ConfigError(f"{ctx}: a features list needs target = \"vx_dot\" (or make features "
                              "a table keyed by target)")
        by_target = {spec["target"]: feats}
        names = {spec["target"]: spec.get("names")}
        inputs = {spec["target"]: spec.get("inputs")}
    elif isinstance(feats, dict) and feats:
        if "target" in spec:
            raise ConfigError(f"{ctx}: give either target + a features list or a features table, "
                              "not both")
        by_target = feats
        names = _per_target(spec.get("names"), feats, f"{ctx}: names")
        inputs = _per_target(spec.get("inputs"), feats, f"{ctx}: inputs")
    else:
        raise ConfigError(f"{ctx}: features must be a non-empty list of expressions or a table "
                          "target -> list")
    terms, input_names = {}, {}
    for target, texts in by_target.items():
        if not isinstance(target, str) or not _IDENT.match(target):
            raise ConfigError(f"{ctx}: target {target!r} is not a signal-like name such as vx_dot")
        if target in allowed_signals:
            raise ConfigError(f"{ctx}: target {target!r} is a signal; targets are derivatives "
                              "such as vx_dot")
        texts = _str_list(texts, f"{ctx}: features for {target}")
        if not texts:
            raise ConfigError(f"{ctx}: no features for {target}")
        fnames = names.get(target)
        if fnames is None:
            fnames = [f"{name}_{target}_{i + 1}" if len(texts) > 1 else f"{name}_{target}"
                      for i in range(len(texts))]
            fnames = [re.sub(r"\W", "_", n) for n in fnames]
        else:
            fnames = _str_list(fnames, f"{ctx}: names for {target}")
            if len(fnames) != len(texts):
                raise ConfigError(f"{ctx}: {len(fnames)} names for {len(texts)} features of {target}")
            for n in fnames:
                if not _IDENT.match(n):
                    raise ConfigError(f"{ctx}: feature name {n!r} is not an identifier")
            if len(set(fnames)) != len(fnames):
                raise ConfigError(f"{ctx}: duplicate feature names for {target}")
        feats_t = []
        for i, (fn, text) in enumerate(zip(fnames, texts)):
            expr = parse_expression(text, allowed_signals, params,
                                    what=f"{ctx}, feature {i + 1} of {target}")
            if not expr.free_symbols:
                raise ConfigError(f"{ctx}: feature {i + 1} of {target} ({text!r}) uses no signal; "
                                  "a constant feature duplicates the intercept")
            feats_t.append(PriorFeature(fn, expr, text))
        terms[target] = tuple(feats_t)
        if inputs.get(target) is not None:
            ins = _str_list(inputs[target], f"{ctx}: inputs for {target}")
            unknown = [s for s in ins if s not in allowed_signals]
            if unknown:
                raise ConfigError(f"{ctx}: input {unknown[0]!r} is neither canonical nor listed in "
                                  "signals")
            input_names[target] = tuple(ins)
    desc = spec.get("description", f"user prior from {where}")
    if not isinstance(desc, str):
        raise ConfigError(f"{ctx}: description must be a string")
    vehicle = spec.get("vehicle", "any")
    if vehicle not in VEHICLE_KINDS:
        raise ConfigError(f"{ctx}: vehicle must be one of {', '.join(VEHICLE_KINDS)}; got {vehicle!r}"
                          f"{did_you_mean(str(vehicle), VEHICLE_KINDS)}")
    extra = {"vehicle": vehicle}
    if "constraints" in spec:
        cpath = spec["constraints"]
        if not isinstance(cpath, str) or not cpath.endswith(".toml"):
            raise ConfigError(f"{ctx}: constraints must name a constraints TOML file; got {cpath!r}")
        cpath = base / cpath
        if not cpath.is_file():
            raise ConfigError(f"{ctx}: constraints file {str(cpath)!r} not found")
        extra["constraints"] = str(cpath)
    return PriorModel(name, desc, terms, input_names, {k: float(v) for k, v in params.items()}, **extra)


def _str_list(v, what: str) -> list[str]:
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        raise ConfigError(f"{what} must be a list of strings, got {v!r}")
    return list(v)


def _per_target(v, feats: dict, what: str) -> dict:
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise ConfigError(f"{what} must be a table keyed by target when features is a table")
    extra = [k for k in v if k not in feats]
    if extra:
        raise ConfigError(f"{what}: target {extra[0]!r} has no features")
    return v
