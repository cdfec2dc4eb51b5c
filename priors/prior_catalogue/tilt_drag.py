"""``tilt-drag``: the paper's empirical quadrotor model (eqs. 18-19), params ``g`` = 9.81 m/s²,
``k_D`` = 0.28 1/s, in droneid's angles (φ roll, θ pitch positive nose down, ψ yaw CCW from east)::

    vx_dot = g cosψ tanθ / cosφ + g sinψ tanφ − k_D vx
    vy_dot = g sinψ tanθ / cosφ − g cosψ tanφ − k_D vy
"""
from __future__ import annotations

import sympy as sp

from droneid.core.expressions import symbol

from ..base import PriorFeature, PriorModel, check_param

#: the prior's name and its place among the built-in priors
NAME, ORDER = "tilt-drag", 10


def tilt_drag(g: float = 9.81, k_D: float = 0.28) -> PriorModel:
    """The paper's empirical drone model (eqs. 18-19): thrust tilt in the world frame plus
    linear drag, in droneid's angles (roll φ, pitch θ positive nose down, yaw ψ CCW from east)."""
    g, k_D = check_param("tilt-drag", "g", g), check_param("tilt-drag", "k_D", k_D)
    vx, vy, phi, theta, psi = (symbol(n) for n in ("vx", "vy", "roll", "pitch", "yaw"))
    G, K = sp.Float(g), sp.Float(k_D)
    terms = {
        "vx_dot": (
            PriorFeature("g_cos_yaw_tan_pitch_over_cos_roll", G * sp.cos(psi) * sp.tan(theta) / sp.cos(phi),
                         "forward tilt (pitch) thrust component along world x", "tilt"),
            PriorFeature("g_sin_yaw_tan_roll", G * sp.sin(psi) * sp.tan(phi),
                         "sideways tilt (roll) thrust component along world x", "tilt"),
            PriorFeature("minus_kD_vx", -K * vx, "linear drag along world x", "drag"),
        ),
        "vy_dot": (
            PriorFeature("g_sin_yaw_tan_pitch_over_cos_roll", G * sp.sin(psi) * sp.tan(theta) / sp.cos(phi),
                         "forward tilt (pitch) thrust component along world y", "tilt"),
            PriorFeature("minus_g_cos_yaw_tan_roll", -G * sp.cos(psi) * sp.tan(phi),
                         "sideways tilt (roll) thrust component along world y", "tilt"),
            PriorFeature("minus_kD_vy", -K * vy, "linear drag along world y", "drag"),
        ),
    }
    return PriorModel(
        "tilt-drag",
        "Empirical quadrotor model of the paper (eqs. 18-19): horizontal acceleration from the "
        "tilted thrust at hover balance plus linear drag -k_D v.",
        terms,
        {"vx_dot": ("vx", "pitch", "roll", "yaw"), "vy_dot": ("vy", "pitch", "roll", "yaw")},
        {"g": g, "k_D": k_D}, vehicle="multirotor", factory=tilt_drag,
    )


FACTORY = tilt_drag
