"""Vertical drag: aerodynamic drag growing with climb rate squared.

Feature for v̇z only: −|vz|·vz (coefficient ``c_z``) -> vertical c_D/m in 1/m.

Precondition: the climb rate reaches ``MIN_VZ_M_S`` (0.5 m/s, 98th percentile of |vz|).
"""
import sympy as sp

from droneid.core.expressions import symbol
from priors.effects import Effect, Interpretation, high, must_be_positive

MIN_VZ_M_S = 0.5


def _preconditions(ctx):
    v = high(ctx.columns["vz"])
    if v < MIN_VZ_M_S:
        return f"the climb rate reaches only {v:.2g} m/s (< {MIN_VZ_M_S:g} m/s)"
    return None


def _features(ctx, consts):
    vz = symbol("vz")
    return {"c_z": -sp.Abs(vz) * vz}


def _interpret(coef, base):
    c = coef.get("c_z", float("nan"))
    return Interpretation(f"vertical quadratic drag c_Dz/m = {c:.3g} 1/m", {"c_D_z_over_m_per_m": c})


def _plausible(values):
    return must_be_positive(values.get("c_D_z_over_m_per_m", float("nan")), "vertical drag c_Dz/m = {:.3g} 1/m")


EFFECT = Effect("vertical_drag", "vertical aerodynamic drag growing with climb rate squared: −c_z|vz|vz",
                (("vz",),), _interpret, expr_fn=_features, data_fn=_preconditions,
                plausible_fn=_plausible, targets=("vz_dot",),
                explain_signal="vz", order=20)
