"""Rotor thrust as prior features: where the thrust comes from in a log (motor speeds, motor
commands, collective thrust or throttle), its magnitude terms, and the thrust direction.

Shared by the rotor-thrust prior (:mod:`priors.prior_catalogue.rotor_thrust`), the choice of
prior for ``auto`` (:func:`priors.registry.choose_prior`), the thrust-related effects
(:func:`priors.effects.thrust_proxy`, ``thrust_curve``, ``battery_sag``), identify and the
simulator.
"""
from __future__ import annotations

import re
from typing import TYPE_CHECKING

from droneid.errors import ConfigError, did_you_mean
from droneid.core.lazy import lazy_module

#: sympy's side: the simulator needs only RPM_SCALE, without sympy
_expressions = lazy_module("droneid.core.expressions")

if TYPE_CHECKING:
    import sympy as sp

# sympy (and droneid.core.expressions, which imports it) inside the functions that build expressions:
# the simulator imports this module for RPM_SCALE, and `droneid simulate` needs no sympy

__all__ = ["THRUST_SOURCES", "RPM_SCALE", "COMMAND_SOURCES", "NOMINAL_EXPO", "body_z_world",
           "thrust_curve", "inverse_thrust_curve", "rotor_speed", "thrust_columns", "motor_count", "in_rpm_unit"]


#: Where the rotor-thrust prior takes the thrust from, most physically direct first:
#: source -> (the signals it needs (``{i}`` = motor index), unit, description)
THRUST_SOURCES = {
    "rpm": ("rpm{i}", "rpm", "motor speeds: thrust = k_T Σ ω_i² (rotor momentum theory)"),
    "motor": ("motor{i}", "1", "motor commands u_i (0..1): thrust = k Σ f_e(u_i), the thrust curve "
              "f_e(u) = (1 − e) u + e u² (ArduPilot's MOT_THST_EXPO form)"),
    "thrust": ("thrust", "N", "collective thrust T (N): specific thrust = T / m"),
    "throttle": ("throttle", "1", "collective command u (0..1): thrust = k f_e(u), the thrust curve "
                 "f_e(u) = (1 − e) u + e u²"),
}
#: the sources whose thrust is a COMMAND mapped through the thrust curve :func:`thrust_curve`
COMMAND_SOURCES = ("motor", "throttle")
#: the thrust curve's shape a command prior is written with before the data choose one
#: (:func:`droneid.fitting.thrust_curve.choose_thrust_curve`): ArduPilot's default MOT_THST_EXPO
NOMINAL_EXPO = 0.65
#: rpm are scaled by this before squaring so coefficients read as numbers near one (1/s² per (10⁴ rpm)²)
RPM_SCALE = 1e4


def body_z_world(roll, pitch, yaw) -> tuple:
    """The body z axis (thrust direction) in the ENU world, exact Z-Y-X rotation (droneid's
    angles: positive pitch = nose down): components (x, y, z), no small-angle form."""
    import sympy as sp
    return (sp.cos(yaw) * sp.sin(pitch) * sp.cos(roll) + sp.sin(yaw) * sp.sin(roll),
            sp.sin(yaw) * sp.sin(pitch) * sp.cos(roll) - sp.cos(yaw) * sp.sin(roll),
            sp.cos(roll) * sp.cos(pitch))


def thrust_curve(u, expo: float):
    """ArduPilot's thrust curve (MOT_THST_EXPO): the thrust of a normalised command ``u`` (0..1)
    relative to full thrust, ``f_e(u) = (1 − e) u + e u²`` (1 at u = 1, 0 at u = 0); ``expo`` e
    in [0, 1]: 0 linear, 1 quadratic (rotor momentum theory with speed ∝ command). Works on
    numbers, numpy arrays (``expo`` too, broadcast) and sympy expressions."""
    if getattr(expo, "ndim", 0):      # an array of shapes: broadcast against ``u`` (numpy)
        return (1.0 - expo) * u + expo * u * u
    e = float(expo)
    return (1.0 - e) * u + e * u * u if e != 1.0 else u * u


def inverse_thrust_curve(f, expo: float):
    """The command ``u`` whose :func:`thrust_curve` is ``f`` (0..1): what ArduPilot's thrust
    linearisation sends for a wanted thrust fraction. Numbers and numpy arrays."""
    import numpy as np

    e = float(expo)
    if e == 1.0:
        return np.sqrt(f)
    if e == 0.0:
        return f
    return (-(1.0 - e) + np.sqrt((1.0 - e) ** 2 + 4.0 * e * f)) / (2.0 * e)


def rotor_speed(q, expo: float):
    """The normalised rotor speed ``w = ω/ω_max`` (0..1) a normalised command ``q`` settles to:
    the speed whose thrust (∝ ω²) is the curve's, ``w = sqrt(f_e(q))``; a command below the
    curve's start asks for 0 (numpy). A rotor's speed is the state with inertia: a motor lag is
    a first-order lag of ``w``, and the rotor then delivers the thrust fraction ``w²`` (the one
    law of :mod:`droneid.fitting.command_thrust` and :mod:`droneid.simulation.motor_model`)."""
    import numpy as np

    e = expo if np.ndim(expo) == 0 else np.asarray(expo, float)
    return np.sqrt(np.maximum(thrust_curve(np.asarray(q, float), e), 0.0))


def thrust_columns(source: str, motors: int = 4, expo: float = NOMINAL_EXPO,
                   v_ref: float | None = None, spin: tuple[float, float] = (0.0, 1.0), rpm_unit: str = "rpm"
                   ) -> tuple[tuple[str, sp.Expr, str], ...]:
    """The thrust magnitude terms of a source: ((name, expr, unit of its coefficient), ...).

    ``rpm``: Σ (ω_i/10⁴)² (``rpm_unit``: the unit the log's motor speeds are in, ``rpm`` or
    ``erpm`` for electrical rpm, named in the coefficient's unit); ``thrust``: T. A command source (:data:`COMMAND_SOURCES`) has ONE
    term, its commands through the thrust curve of shape ``expo`` (:func:`thrust_curve`):
    ``motor``: Σ f_e(u_i); ``throttle``: f_e(u). Two terms (Σu², Σu) would be collinear on any
    flight that stays near hover, and neither is measured: the shape is chosen from the data
    (:mod:`droneid.fitting.thrust_curve`), the scale fitted. ``v_ref`` (V): the commands are scaled by
    the battery voltage the motors see, u·V/v_ref (ArduPilot's voltage scaling), None: not.
    ``spin`` (low, high): the commands where the thrust curve starts and ends (ArduPilot's
    MOT_SPIN_MIN/MAX on the PWM range), u = (command − low)/(high − low); (0, 1): the command.
    """
    import sympy as sp

    symbol = _expressions.symbol
    if source == "rpm":
        w = [symbol(f"rpm{i}") / RPM_SCALE for i in range(1, motors + 1)]
        return (("sum_rpm_sq", sp.Add(*[x ** 2 for x in w]), f"m/s² per (10⁴ {rpm_unit})²"),)
    if source in COMMAND_SOURCES:
        if not (isinstance(expo, (int, float)) and 0.0 <= float(expo) <= 1.0):
            raise ConfigError(f"The 'expo' parameter of the thrust curve must be in [0, 1]. Got {expo!r} instead.")
        scale = symbol("battery_voltage") / sp.Float(v_ref) if v_ref else sp.Integer(1)
        lo, hi = (float(x) for x in spin)
        if not 0.0 <= lo < hi <= 1.0:
            raise ConfigError(f"The 'spin' parameter of the thrust curve must be 0 <= low < high <= 1. "
                              f"Got {spin!r} instead.")

        def norm(n):
            u = symbol(n)
            return u if (lo, hi) == (0.0, 1.0) else (u - sp.Float(lo)) / sp.Float(hi - lo)
        names = [f"motor{i}" for i in range(1, motors + 1)] if source == "motor" else ["throttle"]
        expr = sp.Add(*[thrust_curve(norm(n) * scale, expo) for n in names])
        return (("sum_cmd_curve" if source == "motor" else "throttle_curve", expr, "m/s²"),)
    if source == "thrust":
        return (("thrust_N", symbol("thrust"), "1/kg"),)
    raise ConfigError(f"unknown thrust source {source!r}{did_you_mean(str(source), THRUST_SOURCES)}; "
                      f"sources: {', '.join(THRUST_SOURCES)}")


def motor_count(signals) -> dict[str, int]:
    """{source: N} for the per-motor sources logged for every motor 1..N, N the highest index
    logged. A source with a motor missing below its highest (rpm1, rpm2, rpm4) is left out: a
    sum over some of the motors is no collective thrust (the motors that are there also carry
    the attitude control's differences), so no prior, effect or proxy may sum it."""
    have = {str(n) for n in signals}
    out = {}
    for src in ("rpm", "motor"):
        present = sorted({int(m.group(1)) for n in have if (m := re.fullmatch(rf"{src}(\d+)", n))} - {0})
        if present and present[-1] == len(present):
            out[src] = len(present)
    return out


def in_rpm_unit(prior, units):
    """``prior`` built for the unit the flights' motor speeds are in (``units``: the set of
    ``rpm1`` units over the flights): a rotor-thrust prior on electrical rpm (a reader gives
    ``erpm`` when its source says so) says per (10⁴ erpm)²; any other prior as it is."""
    params = dict(getattr(prior, "params", {}) or {})
    if set(units) != {"erpm"} or params.get("source") != "rpm" or getattr(prior, "factory", None) is None:
        return prior
    try:
        return prior.with_params(rpm_unit="erpm")
    except (ConfigError, TypeError):   # a prior without that parameter keeps its words
        return prior
