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
    """``vx_air``, ``vy_air``, ``speed_air`` (m/s): v − ŵ per flight. ŵ is the Newton step from the
    current estimate ŵ₀ (v − the context's air velocity, 0 at first): the offset measures
    K·w + A·(w − ŵ₀), so ŵ = (K + A)⁻¹(offset + A·ŵ₀), with K = diag(k_D) (1/s) and A =
    ``base["air_jacobian"][flight]`` (1/s: how the drag effects acting on v − ŵ move with ŵ, see
    :func:`droneid.diagnosis.effect_model.air_jacobians`). Without A, or where K + A is singular,
    ŵ = offset / k_D (exact when only the linear drag acts on the air velocity). 0 wind where a
    flight has no offset or k_D ≤ 1e-6."""
    c = ctx.columns
    if "vx" not in c or "vy" not in c:
        return {}
    kd = base.get("k_D") or {}
    jac = base.get("air_jacobian") or {}
    w = {"x": np.zeros(ctx.t.size), "y": np.zeros(ctx.t.size)}
    w0 = {"x": c["vx"] - c.get("vx_air", c["vx"]), "y": c["vy"] - c.get("vy_air", c["vy"])}
    for f, params in coef.items():
        rows = ctx.flight == f
        off = [params.get(f"offset_{axis_of(t)}") for t in HORIZONTAL]
        k = [kd.get(t) for t in HORIZONTAL]
        A = jac.get(f)
        if A is not None and None not in off and all(x is not None and x > _K_MIN for x in k):
            prev = np.array([float(np.mean(w0[axis_of(t)][rows])) if rows.any() else 0.0 for t in HORIZONTAL])
            M = np.diag(k) + np.asarray(A, float)
            est = (np.linalg.solve(M, np.asarray(off, float) + np.asarray(A, float) @ prev)
                   if abs(np.linalg.det(M)) > _K_MIN ** 2 else None)
            if est is not None and np.all(np.isfinite(est)):
                for t, v in zip(HORIZONTAL, est):
                    w[axis_of(t)][rows] = v
                continue
        for t, o, kk in zip(HORIZONTAL, off, k):
            if o is not None and kk is not None and kk > _K_MIN:
                w[axis_of(t)][rows] = o / kk
    vx_air, vy_air = c["vx"] - w["x"], c["vy"] - w["y"]
    return {"vx_air": vx_air, "vy_air": vy_air, "speed_air": np.hypot(vx_air, vy_air)}


EFFECT = Effect("wind", "constant world-frame wind w: linear drag acts on v − w, a constant k_D·w "
                "per axis (the base refit has no intercept, so the offset is not absorbed)",
                (("vx", "vy"),), _interpret, column_fn=_features, explain_signal="yaw",
                per_flight=True, fold_reason=PER_FLIGHT_REASON, refine_fn=_air_velocity, order=30)
