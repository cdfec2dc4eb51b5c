"""A thrust-based prior written as ONE module, the way a user adds one: no line of droneid's
pipeline names it. Issue 27: it must get hover calibration and its own constraints anyway.

``lifting-body``: thrust k_T Σ(ω_i/10⁴)² along the body z axis, gravity, quadratic drag
−c |v| v (a different drag law from rotor-thrust's linear one, so nothing is borrowed by name).
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from droneid.core.expressions import symbol
from droneid.core.targets import TARGETS
from priors import constraints as pc
from priors.base import PriorFeature, PriorModel
from priors.thrust import body_z_world, thrust_columns

NAME, ORDER = "lifting-body", 90


def lifting_body(k_T: float = 0.05, c_D: float = 0.1, g: float = 9.81) -> PriorModel:
    (_, sum_sq, _), = thrust_columns("rpm", 4)
    b = dict(zip("xyz", body_z_world(*(symbol(n) for n in ("roll", "pitch", "yaw")))))
    terms, inputs = {}, {}
    for t in TARGETS.values():
        v = symbol(t.velocity)
        feats = [PriorFeature(f"lift_{t.axis}", sp.Float(k_T) * sum_sq * b[t.axis], "rotor lift", "thrust",
                              magnitude=sp.Float(k_T) * sum_sq),
                 PriorFeature(f"quad_drag_{t.axis}", -sp.Float(c_D) * sp.Abs(v) * v, "quadratic drag", "drag")]
        if t.axis == "z":
            feats.append(PriorFeature("minus_g", sp.Float(-g), "gravity", "gravity"))
        terms[t.name] = tuple(feats)
        inputs[t.name] = (t.velocity, "roll", "pitch", "yaw", "rpm1", "rpm2", "rpm3", "rpm4")
    return PriorModel(NAME, "a lifting body with quadratic drag", terms, inputs,
                      {"k_T": k_T, "c_D": c_D, "g": g}, vehicle="multirotor", constraints=free_fall,
                      intercept={t: (0.0, 0.0) for t in terms}, hover_param="k_T", factory=lifting_body)


def free_fall(prior: PriorModel, target: str, columns) -> tuple:
    """Its own constraint set, built from the data: with no rotor turning and at rest, only
    gravity acts (v̇z = −g, v̇x = v̇y = 0) at any attitude up to 30°."""
    axis, a = TARGETS[target].axis, np.pi / 6
    c = pc.Constraint(f"{target}: free fall with the rotors stopped",
                      {TARGETS[target].velocity: 0.0, **{f"rpm{i}": 0.0 for i in range(1, 5)},
                       "roll": (-a, a), "pitch": (-a, a), "yaw": (-np.pi, np.pi)},
                      "eq", -prior.params["g"] if axis == "z" else 0.0, target)
    top = {s: (0.0, float(np.max(columns[s]))) for s in prior.thrust_signals(target)}
    return pc.ConstraintSet(target, (c,), name="lifting-body free fall"), top


FACTORY = lifting_body
