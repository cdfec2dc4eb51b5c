"""Rotor torques as prior features: the frame's motor layout and how rotor thrusts mix into
body torques (issue 28).

A multirotor's body torques (FLU body) come from its rotors:

* roll and pitch from differences of the rotor thrusts: ``τx = Σ y_i T_i``, ``τy = −Σ x_i T_i``
  with ``(x_i, y_i)`` the rotor's position (FLU, forward and left of the centre);
* yaw from the rotors' drag torques: ``τz = Σ σ_i k_m ω_i²`` with ``σ_i = +1`` for a rotor
  turning clockwise seen from above (its reaction on the body is counter-clockwise, +z in FLU)
  and −1 for counter-clockwise; plus the reaction to the rotors' angular acceleration,
  ``−J_r Σ (−σ_i) ω̇_i``, which is the same pattern applied to the speed rates;
* the gyroscopic term ``−ω × Jω``.

With ``T_i = k_T ω_i²`` each torque is a fixed **pattern** of ``ω_i²``, read from the layout:
:meth:`RotorLayout.patterns`. Constraints, as data: every pattern sums to zero over the rotors
(equal rotor speeds and no rotation give no torque), and the three patterns are orthogonal for a
symmetric frame (checked by :meth:`RotorLayout.check`).

Layouts: :data:`LAYOUTS` by name (positions in arm lengths). A log's declaration (ArduPilot
FRAME_CLASS/FRAME_TYPE, PX4 CA_ROTOR*) maps to a name; failing one, the sign pattern is identified
from the data (:func:`droneid.rotation.model.identify_layout`) and reported.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from droneid.errors import ConfigError, did_you_mean

__all__ = ["RotorLayout", "LAYOUTS", "get_layout", "AXES"]

#: the three body axes, FLU
AXES = ("roll", "pitch", "yaw")


@dataclass(frozen=True)
class RotorLayout:
    """Rotor positions and spin directions in the vehicle's motor order.

    ``x``, ``y``: rotor positions forward and left of the centre (FLU, any unit: arm lengths);
    ``spin``: +1 clockwise seen from above (reaction torque +z), −1 counter-clockwise.
    """
    name: str
    x: tuple[float, ...]
    y: tuple[float, ...]
    spin: tuple[float, ...]
    source: str = ""

    def __post_init__(self):
        if not (len(self.x) == len(self.y) == len(self.spin)) or len(self.x) < 3:
            raise ConfigError(f"rotor layout {self.name!r}: x, y and spin must have one entry per "
                              f"rotor (at least 3); got {len(self.x)}, {len(self.y)}, {len(self.spin)}")

    @property
    def motors(self) -> int:
        return len(self.x)

    def patterns(self) -> np.ndarray:
        """(3, M): per rotor, the roll, pitch and yaw torque per unit ``ω_i²`` (up to the scales
        ``k_T·arm`` and ``k_m``): ``y_i``, ``−x_i`` and ``spin_i``."""
        return np.array([self.y, [-v for v in self.x], self.spin], dtype=float)

    def check(self, tol: float = 1e-9) -> None:
        """The layout's constraints: each pattern sums to zero (equal speeds, no torque)."""
        p = self.patterns()
        bad = [AXES[k] for k in range(3) if abs(p[k].sum()) > tol * max(1.0, np.abs(p[k]).sum())]
        if bad:
            raise ConfigError(f"rotor layout {self.name!r}: equal rotor speeds would give a "
                              f"{', '.join(bad)} torque (the pattern does not sum to zero)")

    def mix(self, w_sq: np.ndarray) -> np.ndarray:
        """(…, 3) roll, pitch, yaw pattern sums of per-rotor values (…, M), e.g. ``ω_i²``."""
        return np.asarray(w_sq, float) @ self.patterns().T


_S = math.sqrt(0.5)

#: name -> layout. ``crazyflie_x``: Crazyflie 2.x motor order M1 front-right, M2 back-right,
#: M3 back-left, M4 front-left, spins as in the nanodrone benchmark's mixer
#: (``τz ∝ −(ω1² + ω3²) + (ω2² + ω4²)``). ``quad_x``: ArduPilot FRAME_CLASS=1 FRAME_TYPE=1 and
#: PX4's quadrotor x (motor 1 front-right CCW, 2 back-left CCW, 3 front-left CW, 4 back-right CW).
LAYOUTS: dict[str, RotorLayout] = {
    "crazyflie_x": RotorLayout("crazyflie_x", x=(_S, -_S, -_S, _S), y=(-_S, -_S, _S, _S),
                               spin=(-1.0, 1.0, -1.0, 1.0),
                               source="Crazyflie 2.x motor order; nanodrone benchmark mixer"),
    "quad_x": RotorLayout("quad_x", x=(_S, -_S, _S, -_S), y=(-_S, _S, _S, -_S),
                          spin=(-1.0, -1.0, 1.0, 1.0),
                          source="ArduPilot FRAME_CLASS=1/FRAME_TYPE=1, PX4 quadrotor x"),
}


def get_layout(name: str) -> RotorLayout:
    """A layout of :data:`LAYOUTS` by name (a typo gets a suggestion)."""
    if name not in LAYOUTS:
        raise ConfigError(f"unknown rotor layout {name!r}{did_you_mean(str(name), LAYOUTS)}; "
                          f"layouts: {', '.join(LAYOUTS)}")
    return LAYOUTS[name]
