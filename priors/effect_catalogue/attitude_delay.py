"""Attitude delay: the logged attitude lags the acceleration it causes by τ.

Feature (v̇x, v̇y, v̇z): dG/dt from the logged attitude (smoothed derivative, coefficient ``tau``
in s, shared) -> "attitude lags by τ": G(att(t + τ)) ≈ G + τ dG/dt. Not foldable: it needs a
time derivative.
"""
from droneid.core.targets import TARGETS
from priors.effects import TILT, Effect, Interpretation


def _features(ctx, consts):
    return {"tau": ctx.d_dt(ctx.columns["G"])}


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
