"""Attitude delay: the logged attitude lags the acceleration it causes by τ.

Feature (v̇x, v̇y, v̇z): the part of dG/dt that comes from the attitude,
Σ_a ∂G/∂a · da/dt over a = roll, pitch, yaw (smoothed derivatives of the logged angles, yaw
unwrapped; coefficient ``tau`` in s, shared) -> "attitude lags by τ":
G(att(t + τ), T(t)) ≈ G + τ Σ_a ∂G/∂a · da/dt. Only the attitude is delayed: with a thrust term
from logged motor speeds or thrust (rotor-thrust), dG/dt also holds dT/dt, the change of the
thrust's magnitude, which is not delayed (on v̇z it is nearly all of dG/dt), so the whole dG/dt
would fit a stand-in and dilute a real delay. A prior whose G has no angle symbols falls back to
dG/dt. Not foldable: it needs a time derivative.
"""
import numpy as np

from droneid.expressions import symbol
from droneid.targets import TARGETS
from priors.effects import TILT, Effect, Interpretation

#: the attitude angles whose lag the effect models (the prior's G reads them)
ANGLES = ("roll", "pitch", "yaw")


def attitude_rate_part(ctx) -> np.ndarray:
    """Σ_a ∂G/∂a · da/dt (m/s³) over the angles G uses (each angle unwrapped per flight, then
    :meth:`priors.effects.EffectContext.d_dt`); dG/dt when G uses none of them."""
    used = [a for a in ANGLES if a in ctx.columns and ctx.tilt is not None
            and symbol(a) in ctx.tilt.free_symbols]
    if not used:
        return ctx.d_dt(ctx.columns["G"])
    out = np.zeros(ctx.t.size)
    for a in used:
        x = np.asarray(ctx.columns[a], float).copy()
        for f in np.unique(ctx.flight):
            m = ctx.flight == f
            x[m] = np.unwrap(x[m])
        out += ctx.tilt_partial(a) * ctx.d_dt(x)
    return out


def _features(ctx, consts):
    return {"tau": attitude_rate_part(ctx)}


def _interpret(coef, base):
    tau = coef.get("tau", float("nan"))
    word = "lags" if tau >= 0 else "leads"
    return Interpretation(f"attitude {word} acceleration by {abs(tau) * 1000:.0f} ms",
                          {"delay_ms": tau * 1000.0})


#: largest attitude delay (s) taken for an estimator's or a stream's lag
MAX_DELAY_S = 0.3


def _plausible(values):
    d = values.get("delay_ms", float("nan")) / 1000.0
    if not 0 < d <= MAX_DELAY_S:
        if d < 0:
            return (f"the fitted attitude leads the acceleration by {abs(d) * 1000:.0f} ms (a lead "
                    "needs a clock error, not an attitude delay)")
        return (f"the fitted attitude lags the acceleration by {d * 1000:.0f} ms (more than "
                f"{MAX_DELAY_S * 1000:.0f} ms: not an estimator's lag)")
    return None


EFFECT = Effect("attitude_delay", "logged attitude lags the acceleration it causes by τ: "
                "G(att(t + τ)) ≈ G + τ dG/dt", ((TILT,),), _interpret,
                column_fn=_features, plausible_fn=_plausible, targets=tuple(TARGETS),
                explain_signal="dG/dt",
                fold_reason="needs dG/dt, a time derivative of the logged attitude (not an "
                            "instantaneous function of states and inputs)", order=50)
