"""The identified motor model of a command-driven vehicle: how the logged commands (and the
battery voltage) become the thrust the v̇ models see, open loop and in the exported vehicle.

identify's plan (:mod:`droneid.fitting.thrust_curve`) chooses, from the training flights, the
thrust curve ``f_e(q) = (1 − e)·q + e·q²`` of the normalised command ``q = n(u)·s``, with
``n(u) = (u − spin_min)/(spin_max − spin_min)`` (the log's MOT_SPIN_MIN/MAX, else 0 and 1) and
``s = V/V_ref`` where the battery compensation was kept (V the logged battery voltage in volts,
V_ref in volts; else ``s = 1``), and a first-order motor lag of time constant ``τ`` (s) where the
block test kept one. The curve and the compensation are written into the final v̇ models'
expressions already (they read ``motor1..N`` or ``throttle`` and ``battery_voltage``); only the
lag is not: the models were fitted on the commands as logged (read at the plan's offset).

The lag, physically. A rotor's speed ω is the state with inertia (J ω̇ = motor torque − drag
torque; linearised, a first-order lag of time constant τ), and its thrust is ∝ ω². So
:class:`MotorModel` lags the NORMALISED ROTOR SPEED ``w = ω/ω_max`` (dimensionless, 0..1) behind
the speed the command asks for, ``w* = sqrt(f_e(q))`` (the speed whose thrust is the curve's:
thrust ∝ w²): ``dw/dt = (w* − w)/τ``. The rotor then delivers the thrust fraction ``w²``, and the
v̇ models are fed the EFFECTIVE command ``ũ`` whose curve gives that thrust (``f_e(n(ũ)·s) = w²``),
so every term that reads a command (the thrust term, any evolved term) sees what the rotor
delivers. identify's profile fits the same law (:mod:`droneid.fitting.command_thrust`: each
rotor's speed :func:`priors.thrust.rotor_speed` lagged, thrust ∝ Σ w²), so τ here is the τ fitted.

The logged commands are the inputs, so the lag is a causal filter of them: the rotor speeds at a
start time are the filter's state from the commands before it (the only information there is
about them; no log holds them), and the same filter runs on inside a window. Discretised exactly
for a command held over each step of ``dt_s`` (zero-order hold, as every input of the open-loop
simulation): with ``a = exp(−dt/τ)``, the speed over step k averages
``w̄_k = w*_k + (w_k − w*_k)·τ/dt·(1 − a)`` (held over the step) and ends at
``w_{k+1} = w*_k + (w_k − w*_k)·a``; it starts at rest on the first command (``w_0 = w*_0``).
A command below the curve's start (``f_e < 0``) asks for speed 0 (a rotor pushes no negative
thrust through a lag).

The lag and the offset. The plan chose the lag with the commands read at t, and the offset of
the thrust inputs without a lag: both describe how the commands lead their thrust, so where a lag
was kept the commands and the voltage are read at t through the lag, not also at the offset
(that would count the lead twice); without a lag they are read at the offset the models record.
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from priors.thrust import COMMAND_SOURCES, NOMINAL_EXPO, rotor_speed

from droneid.core.frames import quat_to_matrix
from droneid.errors import DataError

__all__ = ["MotorModel", "NominalCommandPhysics", "COMMAND_SIGNAL", "is_command", "is_input_signal"]

#: a logged command of one motor (``motor1``..) or the collective ``throttle``
COMMAND_SIGNAL = re.compile(r"motor\d+|throttle")
_INPUT_SIGNAL = re.compile(r"rpm\d+|motor\d+|throttle|battery_voltage")


def is_command(name: str) -> bool:
    """Whether ``name`` is a logged command (``motor<i>`` or ``throttle``)."""
    return COMMAND_SIGNAL.fullmatch(name) is not None


def is_input_signal(name: str) -> bool:
    """Whether ``name`` is an input the open-loop simulation takes from the log (motor speeds
    ``rpm<i>``, commands ``motor<i>`` / ``throttle``, ``battery_voltage``), not from its state."""
    return _INPUT_SIGNAL.fullmatch(name) is not None


def _inverse(f, e: float):
    """The q >= 0 whose curve is ``f`` >= 0 (numpy)."""
    f = np.maximum(f, 0.0)
    if e <= 0.0:
        return f
    return (-(1.0 - e) + np.sqrt((1.0 - e) ** 2 + 4.0 * e * f)) / (2.0 * e)


@dataclass(frozen=True)
class MotorModel:
    """The identified command-to-thrust path (see the module docstring).

    expo : the curve's shape e in [0, 1]; spin : (spin_min, spin_max) of the normalisation
    v_ref : V_ref in volts of the battery compensation, None where it was not kept
    lag_s : the first-order motor lag τ in seconds (0: none kept)
    """
    expo: float
    spin: tuple = (0.0, 1.0)
    v_ref: float | None = None
    lag_s: float = 0.0

    @classmethod
    def from_record(cls, config: Mapping) -> "MotorModel | None":
        """The motor model a result.json ``config`` records for a command prior (its
        ``prior_params``: expo, spin_min/max, v_ref as the models were written with; its
        ``thrust_curve``: the lag kept), or None for another prior."""
        params = dict(config.get("prior_params") or {})
        if params.get("source") not in COMMAND_SOURCES:
            return None
        curve = dict(config.get("thrust_curve") or {})
        try:
            spin = (float(params.get("spin_min", 0.0)), float(params.get("spin_max", 1.0)))
            v_ref = params.get("v_ref")
            return cls(float(params.get("expo", curve.get("expo", NOMINAL_EXPO))), spin,
                       float(v_ref) if v_ref else None, float(curve.get("lag_s") or 0.0))
        except (TypeError, ValueError):
            raise DataError(f"the result's thrust curve cannot be read: prior_params {params}") from None

    @property
    def lagged(self) -> bool:
        return self.lag_s > 0.0

    def _scale(self, volts) -> np.ndarray:
        """s = V/V_ref (1 without compensation, and where the voltage is not positive)."""
        if self.v_ref is None or volts is None:
            return np.asarray(1.0)
        v = np.asarray(volts, float)
        return np.where(v > 0, v / self.v_ref, 1.0)

    def speeds(self, commands: np.ndarray, volts: np.ndarray | None, dt_s: float) -> np.ndarray:
        """The rotors' normalised speeds w = ω/ω_max (N, M, 0..1) over each step of ``dt_s`` s of
        the logged ``commands`` (N, M, held over each step) with the battery voltage ``volts``
        (N,) V: :func:`priors.thrust.rotor_speed` of each normalised (and compensated) command,
        through the first-order lag where one was kept (then the mean speed over each step; the
        speed is a state driven by the commands). The rotor delivers the thrust fraction w²."""
        u = np.asarray(commands, float)
        lo, hi = self.spin
        s = self._scale(volts)
        s = np.broadcast_to(s, (u.shape[0],))[:, None] if s.ndim else np.full((u.shape[0], 1), float(s))
        target = rotor_speed((u - lo) / (hi - lo) * s, self.expo)
        if not self.lagged or u.shape[0] == 0:
            return target
        a = math.exp(-dt_s / self.lag_s)
        c = self.lag_s / dt_s * (1.0 - a)
        w = target[0].copy()
        mean = np.empty_like(target)
        for k in range(target.shape[0]):      # the rotor speeds: a state driven by the commands
            mean[k] = target[k] + (w - target[k]) * c
            w = target[k] + (w - target[k]) * a
        return mean

    def effective(self, commands: np.ndarray, volts: np.ndarray | None, dt_s: float) -> np.ndarray:
        """The effective commands (N, M) over each step of ``dt_s`` s of the logged ``commands``
        (N, M, held over each step) with the battery voltage ``volts`` (N,) V: what the rotors
        deliver through the lag (:meth:`speeds`), as commands through the identified curve. No
        lag: the commands."""
        u = np.asarray(commands, float)
        if not self.lagged or u.shape[0] == 0:
            return u.copy()
        lo, hi = self.spin
        s = self._scale(volts)
        s = np.broadcast_to(s, (u.shape[0],))[:, None] if s.ndim else np.full((u.shape[0], 1), float(s))
        w = self.speeds(u, volts, dt_s)
        return lo + (hi - lo) * _inverse(w * w, self.expo) / s

    def text(self) -> str:
        """The motor model in words, for reports and the exported file's header."""
        lo, hi = self.spin
        norm = "u" if (lo, hi) == (0.0, 1.0) else f"(u − {lo:g})/({hi:g} − {lo:g})"
        batt = f"·V/{self.v_ref:.4g} V" if self.v_ref is not None else ""
        lag = (f"; each rotor's normalised speed w lags sqrt(f_e(q)) with τ = {1000 * self.lag_s:.0f} ms "
               f"(first order), thrust ∝ w², the commands read at t" if self.lagged else
               "; no motor lag (the commands read at the models' offset)")
        return f"q = {norm}{batt}, thrust ∝ f_e(q) = (1 − {self.expo:.3g})·q + {self.expo:.3g}·q²{lag}"


@dataclass(frozen=True)
class NominalCommandPhysics:
    """The benchmark's ``Physics`` row for a command-driven vehicle: thrust along body z from the
    logged commands (and voltage) through the prior's own thrust law as recorded (its curve,
    compensation and hover-calibrated nominal scale, read at t, no lag, no offset), no drag, the
    body rates held: ``v̇ = R(q) e_z · law(inputs) − g e_z`` (m/s², world ENU).

    ``law``: a callable of {input name: (W,) array} giving the thrust per mass (m/s²) along body z;
    ``names``: the logged inputs it reads (:attr:`droneid.simulation.openloop.StateLog.signals`).
    """
    law: object
    names: tuple
    g: float = 9.81

    def signals(self) -> list[str]:
        return [n for n in self.names if not n.startswith("rpm")]

    def inputs(self, log) -> np.ndarray:
        return np.column_stack([log.column(n) for n in self.names])

    def accel(self, state, u) -> np.ndarray:
        thrust = np.asarray(self.law({n: u[:, i] for i, n in enumerate(self.names)}), float)
        a = quat_to_matrix(state[:, 6:10])[:, :, 2] * np.broadcast_to(thrust, (state.shape[0],))[:, None]
        a[:, 2] -= self.g
        return a

    def ang_accel(self, state, u) -> np.ndarray:
        return np.zeros((state.shape[0], 3))
