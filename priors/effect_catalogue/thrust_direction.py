"""Thrust direction: the exact Z-Y-X thrust geometry instead of the small-angle tilt terms.

Feature for v̇x: G_exact − G, G_exact = g(cosψ tanθ + sinψ tanφ/cosθ) (v̇y: g(sinψ tanθ −
cosψ tanφ/cosθ)), coefficient ``w_exact`` -> weight (1 = exact geometry). Not applicable with a
rotor-thrust prior (exact rotation already).

Precondition: the tilt sqrt(roll² + pitch²) reaches ``MIN_TILT_RAD`` (0.3 rad ≈ 17°, 98th
percentile): the two forms differ by ~g·θ·φ²/2, which below that is under 0.1 m/s².
"""
import numpy as np

import sympy as sp

from droneid.core.expressions import symbol
from priors.effects import TILT, Effect, Interpretation, high

MIN_TILT_RAD = 0.3


def _preconditions(ctx):
    tilt = high(np.hypot(ctx.columns["roll"], ctx.columns["pitch"]))
    if tilt < MIN_TILT_RAD:
        return (f"the tilt reaches only {tilt:.2f} rad (< {MIN_TILT_RAD} rad): the exact and the "
                "small-angle thrust directions do not differ there")
    return None


def _applicable(ctx):
    if ctx.tilt_role == "thrust":
        return "the prior's thrust term uses the exact rotation already (rotor-thrust)"
    return None


def _features(ctx, k):
    r, p, y, g = symbol("roll"), symbol("pitch"), symbol("yaw"), sp.Float(ctx.g)
    if ctx.axis == "x":
        exact = g * (sp.cos(y) * sp.tan(p) + sp.sin(y) * sp.tan(r) / sp.cos(p))
    else:
        exact = g * (sp.sin(y) * sp.tan(p) - sp.cos(y) * sp.tan(r) / sp.cos(p))
    return {"w_exact": exact - ctx.tilt}


def _interpret(coef, base):
    w = coef.get("w_exact", float("nan"))
    return Interpretation(f"exact Z-Y-X thrust direction: weight {w:.2f} on (exact − small-angle) "
                          "tilt terms (1 = exact geometry)", {"weight": w})


EFFECT = Effect("thrust_direction", "exact Z-Y-X thrust geometry instead of the paper's small-angle "
                "tilt terms", ((TILT,), ("roll",), ("pitch",), ("yaw",)), _interpret,
                expr_fn=_features, applicable_fn=_applicable, data_fn=_preconditions,
                explain_signal="pitch", order=90)
