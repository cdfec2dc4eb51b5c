"""Quadratic drag: aerodynamic drag growing with speed squared.

Feature for v̇x (v̇y analogous): −sqrt(vx² + vy²)·vx, one coefficient ``c`` shared by v̇x and v̇y
-> c_D/m in 1/m. Once a wind estimate is in the model the fit uses the air velocity v − ŵ (set by
the wind effect's refine hook); the folded expression uses v (wind is a condition of the flight).

Precondition: the horizontal speed reaches ``MIN_SPEED_M_S`` (1 m/s, 98th percentile) and VARIES
by at least ``MIN_SPEED_SPREAD_M_S`` (0.5 m/s, 2nd-98th percentile): below that, or at a constant
speed (a circle), c|v|v is a linear drag c|v|·v, which the prior's k_D already holds.
"""
import sympy as sp

from droneid.core.expressions import symbol
from droneid.core.targets import velocity_of
from priors.effects import Effect, Interpretation, high, must_be_positive, spread

MIN_SPEED_M_S = 1.0
MIN_SPEED_SPREAD_M_S = 0.5


def _preconditions(ctx):
    speed = ctx.columns.get("speed_air", ctx.columns["speed"])
    v = high(speed)
    if v < MIN_SPEED_M_S:
        return f"the horizontal speed reaches only {v:.2g} m/s (< {MIN_SPEED_M_S:g} m/s)"
    dv = spread(speed)
    if dv < MIN_SPEED_SPREAD_M_S:
        return (f"the horizontal speed varies by only {dv:.2g} m/s (< {MIN_SPEED_SPREAD_M_S:g} m/s): "
                "quadratic drag cannot be told from the linear drag at a near-constant speed")
    return None


def _features(ctx, consts):
    return {"c": -sp.sqrt(symbol("vx") ** 2 + symbol("vy") ** 2) * symbol(velocity_of(ctx.target))}


def _interpret(coef, base):
    c = coef.get("c", float("nan"))
    return Interpretation(f"quadratic drag c_D/m = {c:.3g} 1/m", {"c_D_over_m_per_m": c})


def _plausible(values):
    return must_be_positive(values.get("c_D_over_m_per_m", float("nan")), "quadratic drag c_D/m = {:.3g} 1/m")


EFFECT = Effect("quadratic_drag", "aerodynamic drag growing with speed squared: −c|v|v",
                (("vx",), ("vy",)), _interpret, expr_fn=_features, data_fn=_preconditions,
                plausible_fn=_plausible,
                explain_signal="|v| v_axis", order=10)
