"""Quadratic drag: aerodynamic drag growing with speed squared.

Feature for v̇x (v̇y analogous): −sqrt(vx² + vy²)·vx, one coefficient ``c`` shared by v̇x and v̇y
-> c_D/m in 1/m. Once a wind estimate is in the model the fit uses the air velocity v − ŵ (set by
the wind effect's refine hook); the folded expression uses v (wind is a condition of the flight).
"""
import sympy as sp

from droneid.expressions import symbol
from droneid.targets import velocity_of
from priors.effects import Effect, Interpretation


def _features(ctx, consts):
    return {"c": -sp.sqrt(symbol("vx") ** 2 + symbol("vy") ** 2) * symbol(velocity_of(ctx.target))}


def _interpret(coef, base):
    c = coef.get("c", float("nan"))
    return Interpretation(f"quadratic drag c_D/m = {c:.3g} 1/m", {"c_D_over_m_per_m": c})


EFFECT = Effect("quadratic_drag", "aerodynamic drag growing with speed squared: −c|v|v",
                (("vx",), ("vy",)), _interpret, expr_fn=_features,
                explain_signal="|v| v_axis", order=10)
