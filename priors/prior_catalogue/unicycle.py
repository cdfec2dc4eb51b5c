"""``unicycle``: the paper's TurtleBot 2 prior, targets ``x_dot`` and ``y_dot``::

    x_dot = v_f cos(yaw),  y_dot = v_f sin(yaw)

with the heading φ as the canonical ``yaw`` (counter-clockwise from the world x axis) and the
non-canonical command signals ``v_f`` (forward velocity command, m/s) and ``v_a`` (angular
velocity command, rad/s; an input of the paper's TurtleBot models but not of the prior).
"""
from __future__ import annotations

import sympy as sp

from droneid.core.expressions import symbol

from ..base import PriorFeature, PriorModel

#: the prior's name and its place among the built-in priors
NAME, ORDER = "unicycle", 30


def unicycle() -> PriorModel:
    """The paper's TurtleBot prior: x_dot = v_f cos(yaw), y_dot = v_f sin(yaw)."""
    v_f, yaw = symbol("v_f"), symbol("yaw")
    inputs = ("x", "y", "yaw", "v_f", "v_a")
    return PriorModel(
        "unicycle",
        "Kinematic unicycle (the paper's TurtleBot 2 prior): the robot moves along its heading "
        "yaw at the commanded forward velocity v_f.",
        {"x_dot": (PriorFeature("v_f_cos_yaw", v_f * sp.cos(yaw), "commanded velocity along world x",
                                "kinematic"),),
         "y_dot": (PriorFeature("v_f_sin_yaw", v_f * sp.sin(yaw), "commanded velocity along world y",
                                "kinematic"),)},
        {"x_dot": inputs, "y_dot": inputs}, vehicle="ground", factory=unicycle,
    )


FACTORY = unicycle
