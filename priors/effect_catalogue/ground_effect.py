"""Ground effect: thrust gain near the ground.

Feature (v̇x, v̇y, v̇z): G·exp(−(z − z_ground)/h0), z_ground the 2nd percentile of the training
heights (m), h0 = option ``ground_h0_m`` (default 0.5 m), coefficient ``k_ge`` -> thrust gain at
the ground. Untestable when the training heights span less than h0.
"""
import numpy as np
import sympy as sp

from droneid.expressions import symbol
from droneid.targets import TARGETS
from priors.effects import TILT, Effect, Interpretation


def _constants(ctx):
    return {"z_ground": float(np.percentile(ctx.columns["z"], 2)),
            "h0": float(ctx.options.get("ground_h0_m", 0.5))}


def _heights(ctx):
    """Ground effect is identifiable only when the heights span at least h0 above the lowest
    one: at a nearly constant height exp(−(z − z_ground)/h0) is G plus a tiny G·Δz term that
    fits whatever correlates with height-hold errors, not a ground effect."""
    z = ctx.columns["z"]
    span = float(np.percentile(z, 98) - np.percentile(z, 2))
    h0 = float(ctx.options.get("ground_h0_m", 0.5))
    if span < h0:
        return (f"the training heights span only {span:.2g} m (< h0 = {h0:g} m): a ground "
                "effect cannot be told from a constant thrust gain")
    return None


def _features(ctx, k):
    return {"k_ge": ctx.tilt * sp.exp(-(symbol("z") - sp.Float(k["z_ground"])) / sp.Float(k["h0"]))}


def _interpret(coef, base):
    k = coef.get("k_ge", float("nan"))
    return Interpretation(f"thrust gain near the ground: {100 * k:+.0f} % at the training flights' "
                          "ground height (decaying with height)", {"gain_at_ground": k})


EFFECT = Effect("ground_effect", "thrust gain near the ground (needs height z)", ((TILT,), ("z",)),
                _interpret, expr_fn=_features, constants_fn=_constants, data_fn=_heights,
                targets=tuple(TARGETS), explain_signal="z", order=100)
