"""Ground effect: thrust gain near the ground.

Physics (Cheeseman & Bennett): in ground effect a rotor of radius R at height h gives
T/T∞ = 1/(1 − (R/4h)²) ≈ 1 + (R/4h)² (h > R). Feature (v̇x, v̇y, v̇z): G·(1/(4h))², h = max(z −
z_ground, ``H_MIN_M``) in m, z_ground the KNOWN ground height (option ``ground_z_m``, default 0 m:
mocap and local-position frames have their origin on the floor or at the take-off point);
coefficient ``R2`` (m²) -> rotor radius R = √R2 (the gain at height h is (R/4h)²). (An exp(−h/h0) shape would leave the rest of a 1/h² gain to stand-ins such as a
thrust curve.) h0 = option ``ground_h0_m`` (default 0.5 m, about two rotor diameters of a small
quadrotor) is only the reach of the preconditions.

Preconditions (training data; untestable otherwise, with the reason):

- the ground height is known: at most 2 % of the heights lie more than 0.1 m below z_ground;
- time near the ground: at least 5 % of the samples within h0 of it (a flight that climbs and
  descends well above the ground has no ground effect to see, and exp(−z/h0) would only stand
  in for whatever else varies with height);
- the ground factor exp(−(z − z_ground)/h0) varies by at least 0.1 over the flight (at a
  constant height it cannot be told from a constant thrust gain).
"""
import math

import numpy as np
import sympy as sp

from droneid.core.expressions import symbol
from droneid.core.targets import TARGETS
from priors.effects import TILT, Effect, Interpretation, spread

#: share of samples that must lie within h0 of the ground
NEAR_SHARE = 0.05
#: smallest range (2nd-98th percentile) of the ground factor exp(−(z − z_ground)/h0)
MIN_FACTOR_RANGE = 0.1
#: heights are floored here (m) so the 1/h² feature stays finite on the ground itself
H_MIN_M = 0.05


def _ground(ctx):
    return float(ctx.options.get("ground_z_m", 0.0)), float(ctx.options.get("ground_h0_m", 0.5))


def _preconditions(ctx):
    z = np.asarray(ctx.columns["z"], float)
    zg, h0 = _ground(ctx)
    below = float(np.mean(z < zg - 0.1))
    if below > 0.02:
        return (f"{100 * below:.0f} % of the heights lie below the ground height z = {zg:g} m: "
                "the ground is not at a known height (droneid takes z = 0 m as the ground; the Python "
                "API's DiagnoseConfig(ground_z_m=...) states another; the command line has no option for it)")
    near = float(np.mean(z - zg < h0))
    if near < NEAR_SHARE:
        return (f"only {100 * near:.1f} % of the flight is within h0 = {h0:g} m of the ground "
                f"(z = {zg:g} m; needs {100 * NEAR_SHARE:g} %): no time near the ground")
    rng = spread(np.exp(-(z - zg) / h0))
    if rng < MIN_FACTOR_RANGE:
        return (f"the ground factor exp(−(z − {zg:g})/{h0:g}) varies by only {rng:.2g} (< "
                f"{MIN_FACTOR_RANGE:g}): a ground effect cannot be told from a constant thrust gain")
    return None


def _constants(ctx):
    zg, h0 = _ground(ctx)
    return {"z_ground": zg, "h0": h0}


def _features(ctx, k):
    h = sp.Max(symbol("z") - sp.Float(k["z_ground"]), sp.Float(H_MIN_M))
    return {"R2": ctx.tilt / (4 * h) ** 2}


def _interpret(coef, base):
    r2 = coef.get("R2", float("nan"))
    radius = math.sqrt(r2) if r2 > 0 else float("nan")
    txt = (f"ground effect 1 + (R/4h)² with rotor radius R ≈ {radius:.3g} m" if radius == radius
           else f"ground effect with a negative (R/4h)² coefficient {r2:.3g} m² (not physical)")
    return Interpretation(txt, {"R2_m2": r2, "rotor_radius_m": radius})


#: rotor radii (m) a multirotor can have
RADIUS_RANGE_M = (0.01, 1.0)


def _plausible(values):
    r = values.get("rotor_radius_m", float("nan"))
    lo, hi = RADIUS_RANGE_M
    if not lo <= r <= hi:
        return (f"the fitted ground effect needs a rotor radius of {r:.3g} m (outside {lo}-{hi} m)"
                if r == r else "the fitted ground effect has a negative (R/4h)² coefficient")
    return None


EFFECT = Effect("ground_effect", "thrust gain near the ground (needs height z above a known ground "
                "and time near it)", ((TILT,), ("z",)),
                _interpret, expr_fn=_features, constants_fn=_constants, data_fn=_preconditions,
                plausible_fn=_plausible,
                targets=tuple(TARGETS), explain_signal="z", order=100)
