"""Attitude bias: constant roll/pitch offsets of the logged attitude, per flight.

Features (v̇x, v̇y, v̇z): ∂G/∂roll, ∂G/∂pitch, G the prior's thrust-direction terms (coefficients
``d_roll``, ``d_pitch`` in rad, shared by the targets, one per flight) -> bias = −coef
(logged − true). They rotate with yaw, unlike wind. Not foldable: a condition of the flight.
"""
import math

from droneid.targets import TARGETS
from priors.effects import PER_FLIGHT_REASON, TILT, Effect, Interpretation


def _features(ctx, consts):
    return {"d_roll": ctx.tilt_partial("roll"), "d_pitch": ctx.tilt_partial("pitch")}


def _interpret(coef, base):
    # acceleration = G(logged + δ) ≈ G + δ ∂G; bias = logged − true = −δ
    br = -math.degrees(coef.get("d_roll", float("nan")))
    bp = -math.degrees(coef.get("d_pitch", float("nan")))
    return Interpretation(f"roll bias {br:+.2f}°, pitch bias {bp:+.2f}° (logged − true)",
                          {"roll_bias_deg": br, "pitch_bias_deg": bp})


EFFECT = Effect("attitude_bias", "constant roll/pitch offsets of the logged attitude (rotate with "
                "yaw, unlike wind)", ((TILT,), ("roll",), ("pitch",)), _interpret,
                column_fn=_features, targets=tuple(TARGETS), explain_signal="yaw", per_flight=True,
                fold_reason=PER_FLIGHT_REASON, order=40)
