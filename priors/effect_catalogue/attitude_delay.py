"""Attitude delay: the logged attitude lags the acceleration it causes by τ.

Feature (v̇x, v̇y, v̇z): dG/dt from the logged attitude (smoothed derivative, coefficient ``tau``
in s, shared) -> "attitude lags by τ": G(att(t + τ)) ≈ G + τ dG/dt. Not foldable: it needs a
time derivative.
"""
from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from droneid.core.targets import TARGETS
from droneid.core.expressions import evaluate_expr
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
                  flight: np.ndarray, half_window_s: float = 0.1,
                  weights: Sequence[float] | None = None) -> np.ndarray | None:
    """The change of the weighted terms' sum per second of attitude alignment (units of the terms
    per s): Σ w_i ∂term_i/∂angle · d(angle)/dt over the Euler angles the ``terms`` read (yaw
    unwrapped), the other signals (the thrust's motor speeds) held, ``weights`` the terms'
    fitted coefficients (None: 1 each): ``Σ w_i term_i(att(t + τ)) ≈ Σ w_i term_i + τ ·`` this, so
    its coefficient is the alignment τ in s. Unlike the effect's dG/dt it leaves the thrust
    magnitude's own rate out (its timing is the thrust offset's). Rows where it cannot be
    evaluated are NaN (a fit leaves them out). None when no term reads an angle the columns
    have, or a term's derivative reads a signal they lack."""
    n = np.asarray(t).size
    out = np.zeros(n)
    found = False
    for term, w in zip(terms, weights if weights is not None else [1.0] * len(terms), strict=True):
        for sym in term.free_symbols:
            if sym.name not in ANGLES or sym.name not in columns:
                continue
            part = sp.diff(term, sym)
            if any(s.name not in columns for s in part.free_symbols):
                return None
            angle = np.array(columns[sym.name], float)
            if sym.name == "yaw":
                ok = np.isfinite(angle)
                angle[ok] = np.unwrap(angle[ok])
            rate = time_derivative(angle, t, flight, half_window_s)
            out = out + float(w) * evaluate_expr(part, columns, n) * rate
            found = True
    return out if found else None


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
