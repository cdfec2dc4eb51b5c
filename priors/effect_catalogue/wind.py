"""Wind: a constant world-frame wind w per flight; linear drag acts on the air velocity v − w.

Feature for v̇x (v̇y analogous): 1 (coefficient ``offset_x`` in m/s², one per flight) -> wind
w_x = offset_x / k_D in m/s, k_D the fitted linear drag in 1/s (the base refit has no intercept,
so the offset is not absorbed). Not foldable: a condition of the flight, not of the vehicle.

Refine hook: after every fit that includes the wind, the per-flight estimate ŵ sets the air
velocity ``vx_air``, ``vy_air`` and ``speed_air`` (m/s) in every context, so drag effects
(quadratic_drag, anisotropic_drag) act on v − ŵ.
"""
import math

import numpy as np

from droneid.core.targets import HORIZONTAL, axis_of
from priors.effects import PER_FLIGHT_REASON, Effect, Interpretation

#: the smallest linear drag (1/s) from which a wind is computed (below: no wind, w = 0)
_K_MIN = 1e-6


def _features(ctx, consts):
    return {f"offset_{ctx.axis}": np.ones(ctx.t.size)}


def _interpret(coef, base):
    kd = base.get("k_D") or {}
    w, parts = {}, []
    for ax, tgt in (("x", "vx_dot"), ("y", "vy_dot")):
        if f"offset_{ax}" not in coef:
            continue
        k = kd.get(tgt)
        off = coef[f"offset_{ax}"]
        w[f"w_{ax}_m_s"] = off / k if k and k > _K_MIN else float("nan")
        w[f"offset_{ax}_m_s2"] = off
        parts.append(w[f"w_{ax}_m_s"])
    if len(parts) == 1:
        ax = "x" if "offset_x" in coef else "y"
        txt = f"wind along {ax} ({'east' if ax == 'x' else 'north'}) ≈ {parts[0]:.2g} m/s"
    else:
        txt = "wind ≈ (" + ", ".join(f"{p:.2g}" for p in parts) + ") m/s"
    if any(not math.isfinite(p) for p in parts):
        txt += " (linear drag k_D not positive: wind undetermined; constant offset " + ", ".join(
            f"{v:.3g}" for k, v in w.items() if k.startswith("offset")) + " m/s²)"
    return Interpretation(txt, w)


def _air_velocity(ctx, coef, base):
    """``vx_air``, ``vy_air``, ``speed_air`` (m/s): v − ŵ with ŵ_axis = offset_axis / k_D per
    flight (offsets in m/s², k_D in 1/s); 0 wind where a flight has no offset or k_D ≤ 1e-6."""
    c = ctx.columns
    if "vx" not in c or "vy" not in c:
        return {}
    kd = base.get("k_D") or {}
    w = {"x": np.zeros(ctx.t.size), "y": np.zeros(ctx.t.size)}
    for f, params in coef.items():
        for tgt in HORIZONTAL:
            ax = axis_of(tgt)
            off, k = params.get(f"offset_{ax}"), kd.get(tgt)
            if off is not None and k is not None and k > _K_MIN:
                w[ax][ctx.flight == f] = off / k
    vx_air, vy_air = c["vx"] - w["x"], c["vy"] - w["y"]
    return {"vx_air": vx_air, "vy_air": vy_air, "speed_air": np.hypot(vx_air, vy_air)}


EFFECT = Effect("wind", "constant world-frame wind w: linear drag acts on v − w, a constant k_D·w "
                "per axis (the base refit has no intercept, so the offset is not absorbed)",
                (("vx", "vy"),), _interpret, column_fn=_features, explain_signal="yaw",
                per_flight=True, fold_reason=PER_FLIGHT_REASON, refine_fn=_air_velocity, order=30)
