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

import inspect

import numpy as np
import sympy as sp

from droneid.errors import ConfigError, did_you_mean
from droneid.expressions import symbol

from .base import ROLES, PriorFeature, PriorModel
from .user import load_priors

__all__ = ["PriorFeature", "PriorModel", "PRIORS", "ROLES", "THRUST_SOURCES", "get_prior",
           "load_priors", "tilt_drag", "rotor_thrust", "unicycle", "resolve_prior", "is_prior_spec", "choose_prior", "prior_for",
           "body_z_world", "thrust_columns", "motor_count"]


def tilt_drag(g: float = 9.81, k_D: float = 0.28) -> PriorModel:
    """The paper's empirical drone model (eqs. 18-19): thrust tilt in the world frame plus
    linear drag, in droneid's angles (roll φ, pitch θ positive nose down, yaw ψ CCW from east)."""
    g, k_D = _check_param("tilt-drag", "g", g), _check_param("tilt-drag", "k_D", k_D)
    vx, vy, phi, theta, psi = (symbol(n) for n in ("vx", "vy", "roll", "pitch", "yaw"))
    G, K = sp.Float(g), sp.Float(k_D)
    terms = {
        "vx_dot": (
            PriorFeature("g_cos_yaw_tan_pitch_over_cos_roll", G * sp.cos(psi) * sp.tan(theta) / sp.cos(phi),
                         "forward tilt (pitch) thrust component along world x", "tilt"),
            PriorFeature("g_sin_yaw_tan_roll", G * sp.sin(psi) * sp.tan(phi),
                         "sideways tilt (roll) thrust component along world x", "tilt"),
            PriorFeature("minus_kD_vx", -K * vx, "linear drag along world x", "drag"),
        ),
        "vy_dot": (
            PriorFeature("g_sin_yaw_tan_pitch_over_cos_roll", G * sp.sin(psi) * sp.tan(theta) / sp.cos(phi),
                         "forward tilt (pitch) thrust component along world y", "tilt"),
            PriorFeature("minus_g_cos_yaw_tan_roll", -G * sp.cos(psi) * sp.tan(phi),
                         "sideways tilt (roll) thrust component along world y", "tilt"),
            PriorFeature("minus_kD_vy", -K * vy, "linear drag along world y", "drag"),
        ),
    }
    return PriorModel(
        "tilt-drag",
        "Empirical quadrotor model of the paper (eqs. 18-19): horizontal acceleration from the "
        "tilted thrust at hover balance plus linear drag -k_D v.",
        terms,
        {"vx_dot": ("vx", "pitch", "roll", "yaw"), "vy_dot": ("vy", "pitch", "roll", "yaw")},
        {"g": g, "k_D": k_D}, vehicle="multirotor",
    )


def unicycle() -> PriorModel:
    """The paper's TurtleBot prior: x_dot = v_f cos(yaw), y_dot = v_f sin(yaw)."""
    v_f, yaw = symbol("v_f"), symbol("yaw")
    inputs = ("x", "y", "yaw", "v_f", "v_a")
    return PriorModel(
        "unicycle",
        "Kinematic unicycle (the paper's TurtleBot 2 prior): the robot moves along its heading "
        "yaw at the commanded forward velocity v_f.",
        {"x_dot": (PriorFeature("v_f_cos_yaw", v_f * sp.cos(yaw), "commanded velocity along world x",
                                "kinematic"),),
         "y_dot": (PriorFeature("v_f_sin_yaw", v_f * sp.sin(yaw), "commanded velocity along world y",
                                "kinematic"),)},
        {"x_dot": inputs, "y_dot": inputs}, vehicle="ground",
    )


#: Where the rotor-thrust prior takes the thrust from, most physically direct first:
#: source -> (the signals it needs (``{i}`` = motor index), unit, description)
THRUST_SOURCES = {
    "rpm": ("rpm{i}", "rpm", "motor speeds: thrust = k_T Σ ω_i² (rotor momentum theory)"),
    "motor": ("motor{i}", "1", "motor commands u_i (0..1): thrust = a Σ u_i² + b Σ u_i (a fitted map)"),
    "thrust": ("thrust", "N", "collective thrust T (N): specific thrust = T / m"),
    "throttle": ("throttle", "1", "collective command u (0..1): thrust = a u² + b u (a fitted map)"),
}
#: rpm are scaled by this before squaring so coefficients read as numbers near one (1/s² per (10⁴ rpm)²)
RPM_SCALE = 1e4


def body_z_world(roll, pitch, yaw) -> tuple:
    """The body z axis (thrust direction) in the ENU world, exact Z-Y-X rotation (droneid's
    angles: positive pitch = nose down): components (x, y, z), no small-angle form."""
    return (sp.cos(yaw) * sp.sin(pitch) * sp.cos(roll) + sp.sin(yaw) * sp.sin(roll),
            sp.sin(yaw) * sp.sin(pitch) * sp.cos(roll) - sp.cos(yaw) * sp.sin(roll),
            sp.cos(roll) * sp.cos(pitch))


def thrust_columns(source: str, motors: int = 4) -> tuple[tuple[str, sp.Expr, str], ...]:
    """The thrust magnitude terms of a source: ((name, expr, unit of its coefficient), ...).

    ``rpm``: Σ (ω_i/10⁴)²; ``motor``: Σ u_i² and Σ u_i; ``throttle``: u² and u; ``thrust``: T.
    """
    if source == "rpm":
        w = [symbol(f"rpm{i}") / RPM_SCALE for i in range(1, motors + 1)]
        return (("sum_rpm_sq", sp.Add(*[x ** 2 for x in w]), "m/s² per (10⁴ rpm)²"),)
    if source == "motor":
        u = [symbol(f"motor{i}") for i in range(1, motors + 1)]
        return (("sum_cmd_sq", sp.Add(*[x ** 2 for x in u]), "m/s²"),
                ("sum_cmd", sp.Add(*u), "m/s²"))
    if source == "throttle":
        u = symbol("throttle")
        return (("throttle_sq", u ** 2, "m/s²"), ("throttle_lin", u, "m/s²"))
    if source == "thrust":
        return (("thrust_N", symbol("thrust"), "1/kg"),)
    raise ConfigError(f"unknown thrust source {source!r}{did_you_mean(str(source), THRUST_SOURCES)}; "
                      f"sources: {', '.join(THRUST_SOURCES)}")


def rotor_thrust(source: str = "rpm", motors: int = 4, k_T: float = 0.0257, k_D: float = 0.28,
                 g: float = 9.81, rotor_drag: bool = False) -> PriorModel:
    """Rotor-thrust quadrotor model: logged thrust along the body z axis, gravity, linear drag::

        v̇ = (k_T · thrust(source)) R(roll, pitch, yaw) e3 − g e3 − k_D v   (world ENU)

    ``thrust(source)`` from :data:`THRUST_SOURCES` (``rpm``: Σ(ω_i/10⁴)²). The exact rotation,
    no hover-balance or small-angle assumption, so it models v̇z too. ``k_T`` (m/s² per unit of
    the thrust term: for ``rpm`` per (10⁴ rpm)²) is the nominal scale of the 1-feature form;
    split into terms (the default), least squares tunes every scale. ``rotor_drag`` adds the
    rotor-drag law −k_r (Σ ω_i/10⁴) v (blade flapping and induced drag grow with rotor speed).
    """
    for name, v in (("k_T", k_T), ("k_D", k_D), ("g", g)):
        _check_param("rotor-thrust", name, v)
    if not isinstance(motors, int) or isinstance(motors, bool) or not 1 <= motors <= 16:
        raise ConfigError(f"The 'motors' parameter of prior 'rotor-thrust' must be an integer in 1..16. "
                          f"Got {motors!r} instead.")
    cols = thrust_columns(source, motors)
    roll, pitch, yaw = (symbol(n) for n in ("roll", "pitch", "yaw"))
    b = dict(zip("xyz", body_z_world(roll, pitch, yaw)))
    signals = sorted({s.name for _, e, _ in cols for s in e.free_symbols},
                     key=lambda n: (len(n), n))
    terms, inputs = {}, {}
    for axis in "xyz":
        v = symbol(f"v{axis}")
        feats = [PriorFeature(f"{cname}_{axis}", sp.Float(k_T) * e * b[axis],
                              f"{THRUST_SOURCES[source][2].split(':')[0]} ({cname}) along world {axis}, "
                              f"coefficient in {unit}", "thrust")
                 for cname, e, unit in cols]
        if axis == "z":
            feats.append(PriorFeature("minus_g", sp.Float(-g), "gravity, m/s²", "gravity"))
        feats.append(PriorFeature(f"minus_kD_v{axis}", -sp.Float(k_D) * v, f"linear drag along world {axis}",
                                  "drag"))
        if rotor_drag and source == "rpm":
            s1 = sp.Add(*[symbol(f"rpm{i}") / RPM_SCALE for i in range(1, motors + 1)])
            feats.append(PriorFeature(f"rotor_drag_{axis}", -sp.Float(0.01) * s1 * v,
                                      f"rotor drag −k_r Σ(ω/10⁴) v{axis}", "drag"))
        terms[f"v{axis}_dot"] = tuple(feats)
        inputs[f"v{axis}_dot"] = (f"v{axis}", "roll", "pitch", "yaw", *signals)
    return PriorModel(
        "rotor-thrust",
        f"Rotor-thrust model: {THRUST_SOURCES[source][2]}, along the body z axis rotated by the "
        f"full attitude, minus gravity, minus linear drag k_D v.",
        terms, inputs, {"source": source, "motors": motors, "k_T": k_T, "k_D": k_D, "g": g,
                        "rotor_drag": rotor_drag},
        vehicle="multirotor", constraints="rotor-thrust")


def motor_count(signals) -> dict[str, int]:
    """{source: number of consecutive motors 1..N available} for the per-motor sources."""
    have = set(signals)
    out = {}
    for src in ("rpm", "motor"):
        n = 0
        while f"{src}{n + 1}" in have:
            n += 1
        if n:
            out[src] = n
    return out


def choose_prior(signals, requested: str = "auto") -> tuple[str, dict, str]:
    """(prior name, its parameters, the reason) for ``requested`` on data with these signals.

    ``auto``: the most physical prior the signals support: rotor-thrust from motor speeds, else
    motor commands, else collective thrust, else the collective command; tilt-drag otherwise.
    A motor source counts only with at least 3 motors (a multirotor's worth).
    """
    have = set(signals)
    counts = motor_count(have)
    if requested not in ("auto", "rotor-thrust"):
        return requested, {}, "named by the user"
    for src in THRUST_SOURCES:
        if src in counts and counts[src] >= 3:
            return "rotor-thrust", {"source": src, "motors": counts[src]}, (
                f"the log has {counts[src]} {'motor speeds' if src == 'rpm' else 'motor commands'} "
                f"({src}1..{src}{counts[src]})")
        if src in ("thrust", "throttle") and src in have:
            return "rotor-thrust", {"source": src}, f"the log has the collective {src}"
    if requested == "rotor-thrust":
        raise ConfigError("prior 'rotor-thrust' needs motor speeds (rpm1..), motor commands "
                          "(motor1..), collective thrust or throttle; the data have none of them")
    return "tilt-drag", {}, "the log has no motor speeds, motor commands or thrust"


def _check_param(prior: str, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ConfigError(f"The '{name}' parameter of prior '{prior}' must be a finite number. "
                          f"Got {value!r} instead.")
    return float(value)


#: name -> factory(**params) -> PriorModel
PRIORS = {"tilt-drag": tilt_drag, "rotor-thrust": rotor_thrust, "unicycle": unicycle}


def get_prior(name: str, **params) -> PriorModel:
    """A built-in prior model by name, with its parameters (e.g. ``get_prior("tilt-drag", k_D=0.3)``)."""
    if name not in PRIORS:
        raise ConfigError(f"unknown prior {name!r}{did_you_mean(str(name), PRIORS)}; "
                          f"built-in priors: {', '.join(PRIORS)} (user priors: load_priors(path))")
    accepted = list(inspect.signature(PRIORS[name]).parameters)
    for k in params:
        if k not in accepted:
            raise ConfigError(f"prior '{name}' has no parameter {k!r}{did_you_mean(k, accepted)}; "
                              f"its parameters: {', '.join(accepted) or 'none'}")
    return PRIORS[name](**params)


def prior_for(spec: str | PriorModel, signals) -> tuple[PriorModel, str]:
    """(PriorModel, why) for ``spec`` on data with these ``signals``: ``auto`` (and a bare
    ``rotor-thrust``) choose with :func:`choose_prior`; anything else is :func:`resolve_prior`.
    The one place identify, diagnose and the CLI turn ``--prior`` into a model."""
    if isinstance(spec, str) and spec in ("auto", "rotor-thrust"):
        name, params, why = choose_prior(signals, spec)
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
