"""Attitude delay: the logged attitude lags the acceleration it causes by τ.

Feature (v̇x, v̇y, v̇z): dG/dt from the logged attitude (smoothed derivative, coefficient ``tau``
in s, shared) -> "attitude lags by τ": G(att(t + τ)) ≈ G + τ dG/dt. Not foldable: it needs a
time derivative.
"""
from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from droneid.core.expressions import compile_expression
from droneid.core.targets import TARGETS
from priors.effect_signals import time_derivative
from priors.effects import TILT, Effect, Interpretation

#: the attitude angles (rad, Z-Y-X) an alignment moves
ANGLES = ("roll", "pitch", "yaw")


def _features(ctx, consts):
    return {"tau": ctx.d_dt(ctx.columns["G"])}


def _interpret(coef, base):
    tau = coef.get("tau", float("nan"))
    word = "lags" if tau >= 0 else "leads"
    return Interpretation(f"attitude {word} acceleration by {abs(tau) * 1000:.0f} ms",
                          {"delay_ms": tau * 1000.0})


def attitude_rate(terms: Sequence[sp.Expr], columns: Mapping[str, np.ndarray], t: np.ndarray,
                  flight: np.ndarray, half_window_s: float = 0.1) -> np.ndarray | None:
    """The change of the terms' sum per second of attitude alignment (units of the terms per s):
    Σ ∂term/∂angle · d(angle)/dt over the Euler angles the ``terms`` read (yaw unwrapped), the
    other signals (the thrust's motor speeds) held: ``Σ term(att(t + τ)) ≈ Σ term + τ ·`` this.
    Unlike the effect's dG/dt it leaves the thrust magnitude's own rate out (its timing is the
    thrust offset's). None when no term reads an angle the columns have."""
    out = np.zeros(np.asarray(t).size)
    found = False
    for term in terms:
        for sym in term.free_symbols:
            if sym.name not in ANGLES or sym.name not in columns:
                continue
            part = sp.diff(term, sym)
            names = sorted(s.name for s in part.free_symbols)
            if any(n not in columns for n in names):
                return None
            angle = np.asarray(columns[sym.name], float)
            rate = time_derivative(np.unwrap(angle) if sym.name == "yaw" else angle, t, flight, half_window_s)
            value = compile_expression(part, names)({n: np.asarray(columns[n], float) for n in names} or
                                                   {"_": out})
            out = out + np.broadcast_to(value, out.shape) * rate
            found = True
    return out if found and np.all(np.isfinite(out)) else None


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
