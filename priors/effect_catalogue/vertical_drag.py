"""Vertical drag: aerodynamic drag growing with climb rate squared.

Feature for v̇z only: −|vz|·vz (coefficient ``c_z``) -> vertical c_D/m in 1/m.
"""
import sympy as sp

from droneid.expressions import symbol
from priors.effects import Effect, Interpretation


def _features(ctx, consts):
    vz = symbol("vz")
    return {"c_z": -sp.Abs(vz) * vz}


def _interpret(coef, base):
    c = coef.get("c_z", float("nan"))
    return Interpretation(f"vertical quadratic drag c_Dz/m = {c:.3g} 1/m", {"c_D_z_over_m_per_m": c})


EFFECT = Effect("vertical_drag", "vertical aerodynamic drag growing with climb rate squared: −c_z|vz|vz",
                (("vz",),), _interpret, expr_fn=_features, targets=("vz_dot",),
                explain_signal="vz", order=20)
