"""Attitude bias: constant roll/pitch offsets of the logged attitude, per flight.

Features (v̇x, v̇y, v̇z): ∂G/∂roll, ∂G/∂pitch, G the prior's thrust-direction terms (coefficients
``d_roll``, ``d_pitch`` in rad, shared by the targets, one per flight) -> bias = −coef
(logged − true). They rotate with yaw, unlike wind. Not foldable: a condition of the flight.

Precondition: the heading varies by at least ``MIN_YAW_SPAN_RAD`` (2nd-98th percentile of the
unwrapped yaw, 0.5 rad ≈ 30°) in every training flight: at a constant heading a roll/pitch
offset is exactly a constant world-frame acceleration, i.e. wind, and only wind (the condition
of a flight that needs no faulty sensor) is tried.
"""
import numpy as np

import math

from droneid.core.targets import TARGETS
from priors.effects import PER_FLIGHT_REASON, TILT, Effect, Interpretation, spread

MIN_YAW_SPAN_RAD = 0.5


def _preconditions(ctx):
    yaw = np.asarray(ctx.columns["yaw"], float)
    spans = [spread(np.unwrap(yaw[ctx.flight == f])) for f in np.unique(ctx.flight)]
    if min(spans, default=0.0) < MIN_YAW_SPAN_RAD:
        return (f"the heading spans only {min(spans):.2f} rad (< {MIN_YAW_SPAN_RAD} rad) in a training "
                "flight: an attitude bias cannot be told from wind there")
    return None


def _features(ctx, consts):
    return {"d_roll": ctx.tilt_partial("roll"), "d_pitch": ctx.tilt_partial("pitch")}


def _interpret(coef, base):
    # acceleration = G(logged + δ) ≈ G + δ ∂G; bias = logged − true = −δ
    br = -math.degrees(coef.get("d_roll", float("nan")))
    bp = -math.degrees(coef.get("d_pitch", float("nan")))
    return Interpretation(f"roll bias {br:+.2f}°, pitch bias {bp:+.2f}° (logged − true)",
                          {"roll_bias_deg": br, "pitch_bias_deg": bp})


EFFECT = Effect("attitude_bias", "constant roll/pitch offsets of the logged attitude (rotate with "
                "yaw, unlike wind)", ((TILT,), ("roll",), ("pitch",), ("yaw",)), _interpret,
                column_fn=_features, data_fn=_preconditions, targets=tuple(TARGETS), explain_signal="yaw", per_flight=True,
                fold_reason=PER_FLIGHT_REASON, order=40)
