"""Thrust curve: rotor thrust is not exactly ∝ ω² (inflow, motor and propeller curves).

Feature (v̇x, v̇y, v̇z): G·((Σω/S̄)/(Σω²/W̄) − 1), ω the motor speeds rpm1..rpmN in 10⁴ rpm, S̄, W̄
the training means of Σω and Σω² (coefficient ``a``) -> thrust ∝ ω^(2−a) near the training
mean. Applies only to a rotor-thrust prior whose thrust comes from rpm (G the logged thrust,
exact rotation already).
"""
import numpy as np
import sympy as sp

from droneid.core.expressions import symbol
from droneid.core.targets import TARGETS
from priors.effects import TILT, Effect, Interpretation
from priors.thrust import RPM_SCALE, motor_count


def _rpm_sums(available):
    """(Σ ω_i, Σ ω_i²) over the logged motor speeds rpm1..rpmN, in 10⁴ rpm; None without them."""
    n = motor_count(available).get("rpm", 0)
    if not n:
        return None
    w = [symbol(f"rpm{i}") / int(RPM_SCALE) for i in range(1, n + 1)]
    return sp.Add(*w), sp.Add(*[x ** 2 for x in w])


def _applicable(ctx):
    if ctx.tilt_role != "thrust":
        return "needs a prior whose thrust term comes from motor speeds (rotor-thrust)"
    if _rpm_sums(ctx.columns) is None:
        return "needs motor speeds rpm1..rpmN"
    return None


def _constants(ctx):
    s, w = _rpm_sums(ctx.columns)
    return {"S_mean": float(np.mean(ctx.evaluate(s))), "W_mean": float(np.mean(ctx.evaluate(w)))}


def _features(ctx, k):
    sums = _rpm_sums(ctx.columns)
    if sums is None or not (k.get("S_mean", 0.0) > 0 and k.get("W_mean", 0.0) > 0):
        return {}
    s, w = sums
    return {"a": ctx.tilt * ((s / sp.Float(k["S_mean"])) / (w / sp.Float(k["W_mean"])) - 1)}


def _interpret(coef, base):
    a = coef.get("a", float("nan"))
    return Interpretation(f"rotor thrust grows as ω^{2 - a:.2f} rather than ω² (thrust curve; "
                          f"a = {a:.2f})", {"a": a, "exponent": 2 - a})


#: physically possible exponents of rotor thrust in rotor speed (propellers: about 1.8-2.2)
EXPONENT_RANGE = (1.5, 2.5)


def _plausible(values):
    e = values.get("exponent", float("nan"))
    lo, hi = EXPONENT_RANGE
    if not lo <= e <= hi:
        return f"the fitted thrust exponent {e:.2f} lies outside {lo}-{hi} (not a propeller's)"
    return None


EFFECT = Effect("thrust_curve", "rotor thrust is not exactly ∝ ω² (inflow, motor and propeller "
                "curves): the thrust terms scale with (1 + a·((Σω/S̄)/(Σω²/W̄) − 1)), i.e. T ∝ ω^(2−a) "
                "near the training mean", ((TILT,), ("rpm1",)), _interpret, expr_fn=_features,
                constants_fn=_constants, applicable_fn=_applicable, plausible_fn=_plausible,
                targets=tuple(TARGETS),
                explain_signal="thrust", order=80)
