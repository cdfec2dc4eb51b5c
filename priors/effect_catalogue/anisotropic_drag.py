"""Anisotropic drag: different linear drag along body x and body y.

Feature for v̇x: −(cos2ψ·vx + sin2ψ·vy)/2, for v̇y: −(sin2ψ·vx − cos2ψ·vy)/2 (coefficient ``dk``
in 1/s, shared) -> k_x = k̄ + Δk/2, k_y = k̄ − Δk/2, k̄ the fitted linear drag (1/s). Acts on the
air velocity once a wind estimate is in the model.
"""
import sympy as sp

from droneid.core.expressions import symbol
from priors.effects import Effect, Interpretation, mean_k_drag


def _features(ctx, consts):
    psi, vx, vy = symbol("yaw"), symbol("vx"), symbol("vy")
    c2, s2 = sp.cos(2 * psi), sp.sin(2 * psi)
    if ctx.axis == "x":
        return {"dk": -(c2 * vx + s2 * vy) / 2}
    return {"dk": -(s2 * vx - c2 * vy) / 2}


def _interpret(coef, base):
    k = mean_k_drag(base)
    dk = coef.get("dk", float("nan"))
    kx, ky = k + dk / 2, k - dk / 2
    return Interpretation(f"anisotropic drag k_x = {kx:.3g} 1/s (body forward), "
                          f"k_y = {ky:.3g} 1/s (body left)",
                          {"k_x_per_s": kx, "k_y_per_s": ky, "dk_per_s": dk})


def _plausible(values):
    kx, ky = values.get("k_x_per_s", float("nan")), values.get("k_y_per_s", float("nan"))
    if not (kx >= 0 and ky >= 0):
        return f"the fitted body drags k_x = {kx:.3g}, k_y = {ky:.3g} 1/s are not both ≥ 0"
    return None


EFFECT = Effect("anisotropic_drag", "different linear drag along body x and body y",
                (("vx",), ("vy",), ("yaw",)), _interpret, expr_fn=_features, plausible_fn=_plausible,
                explain_signal="yaw", order=60)
