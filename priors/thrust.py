"""Rotor thrust as prior features: where the thrust comes from in a log (motor speeds, motor
commands, collective thrust or throttle), its magnitude terms, and the thrust direction.

Shared by the rotor-thrust prior (:mod:`priors.prior_catalogue.rotor_thrust`), the choice of
prior for ``auto`` (:func:`priors.registry.choose_prior`), the thrust-related effects
(:func:`priors.effects.thrust_proxy`, ``thrust_curve``, ``battery_sag``), identify and the
simulator.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from droneid.errors import ConfigError, did_you_mean
from droneid.lazy import lazy_module

#: sympy's side: the simulator needs only RPM_SCALE, without sympy
_expressions = lazy_module("droneid.expressions")

if TYPE_CHECKING:
    import sympy as sp

# sympy (and droneid.expressions, which imports it) inside the functions that build expressions:
# the simulator imports this module for RPM_SCALE, and `droneid simulate` needs no sympy

__all__ = ["THRUST_SOURCES", "RPM_SCALE", "body_z_world", "thrust_columns", "motor_count", "in_rpm_unit"]


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
    import sympy as sp
    return (sp.cos(yaw) * sp.sin(pitch) * sp.cos(roll) + sp.sin(yaw) * sp.sin(roll),
            sp.sin(yaw) * sp.sin(pitch) * sp.cos(roll) - sp.cos(yaw) * sp.sin(roll),
            sp.cos(roll) * sp.cos(pitch))


def thrust_columns(source: str, motors: int = 4, rpm_unit: str = "rpm") -> tuple[tuple[str, sp.Expr, str], ...]:
    """The thrust magnitude terms of a source: ((name, expr, unit of its coefficient), ...).

    ``rpm``: Σ (ω_i/10⁴)² (``rpm_unit``: the unit the log's motor speeds are in, ``rpm`` or
    ``erpm`` for electrical rpm, named in the coefficient's unit); ``motor``: Σ u_i² and Σ u_i;
    ``throttle``: u² and u; ``thrust``: T.
    """
    import sympy as sp

    symbol = _expressions.symbol
    if source == "rpm":
        w = [symbol(f"rpm{i}") / RPM_SCALE for i in range(1, motors + 1)]
        return (("sum_rpm_sq", sp.Add(*[x ** 2 for x in w]), f"m/s² per (10⁴ {rpm_unit})²"),)
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
