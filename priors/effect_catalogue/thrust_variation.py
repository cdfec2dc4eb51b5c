"""Thrust variation: thrust departs from hover balance (climbs, descents).

Feature for v̇x (v̇y analogous): G·(T/T̄ − 1), T the logged thrust proxy
(:func:`priors.effects.thrust_proxy`: thrust in N, else Σ(rpm/10⁴)², else the mean motor
command, else throttle), T̄ its training mean (coefficient ``s``) -> gain (1 = thrust
proportional to T). Not applicable when G is the logged thrust already (rotor-thrust).

Precondition: the thrust proxy varies by at least ``MIN_VARIATION`` (5 %, 2nd-98th percentile
range over the mean).
"""
import numpy as np
import sympy as sp

from priors.effects import TILT, Effect, Interpretation, spread, thrust_proxy

_THRUST_SIGNALS = ("thrust", "rpm1", "motor1", "throttle")
MIN_VARIATION = 0.05


def _preconditions(ctx):
    _, e = thrust_proxy(ctx.columns)
    T = ctx.evaluate(e)
    rel = spread(T) / max(abs(float(np.mean(T))), 1e-12)
    if rel < MIN_VARIATION:
        return f"the logged thrust varies by only {100 * rel:.1f} % (< {100 * MIN_VARIATION:g} %)"
    return None


def _applicable(ctx):
    if ctx.tilt_role == "thrust":
        return ("the prior's thrust term is the logged thrust already (rotor-thrust): thrust "
                "variation is in the prior")
    return None


def _constants(ctx):
    _, e = thrust_proxy(ctx.columns)
    return {"T_mean": float(np.mean(ctx.evaluate(e)))}


def _features(ctx, k):
    _, e = thrust_proxy(ctx.columns)
    if not abs(k.get("T_mean", 0.0)) > 1e-12:
        return {}
    return {"s": ctx.tilt * (e / sp.Float(k["T_mean"]) - 1)}


def _interpret(coef, base):
    s = coef.get("s", float("nan"))
    return Interpretation(f"thrust departs from hover balance: the fitted tilt terms scale with "
                          f"(1 + {s:.2f}·(T/T̄ − 1)), T the logged thrust proxy (1 = thrust "
                          "proportional to it)", {"gain": s})


EFFECT = Effect("thrust_variation", "thrust departs from hover balance (climbs, descents): the tilt "
                "terms scale with the logged thrust relative to its training mean",
                ((TILT,), _THRUST_SIGNALS), _interpret, expr_fn=_features,
                constants_fn=_constants, applicable_fn=_applicable, data_fn=_preconditions,
                explain_signal="thrust", order=70)
