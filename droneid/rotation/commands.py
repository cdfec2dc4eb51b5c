"""The rotational model of a command-driven vehicle (issue 36 item 5): each rotor's speed from its
logged command through the identified motor model, so the rotational ladder runs on vehicles that
log motor commands (ArduPilot RCOU, PX4 actuator_outputs) and battery voltage, not rotor speeds.

The plan's motor model (:class:`droneid.simulation.motor_model.MotorModel`: the thrust curve
``f_e(q) = (1 − e)·q + e·q²`` of the normalised command ``q = n(u)·s``, the battery compensation
``s = V/V_ref`` where it was kept, the first-order motor lag τ where it was kept) gives each rotor's
NORMALISED speed ``w_i`` (dimensionless, 0..1 of full speed): ``w_i = sqrt(f_e(q_i))`` read at the
plan's offset without a lag, the lagged speed of :meth:`MotorModel.effective` (the speed over each
step) with one. The rotational model reads these ``w_i`` where it reads rotor speeds elsewhere,
with ``rad_s_per_rpm = SPEED_UNIT`` (1000), so its ``s_i = w_i² = f_e(q_i)``: **each rotor's
thrust as a fraction of its full thrust** (the commands' normalised thrust units), not
``(ω_i / 1000 rad/s)²``. Its torque coefficients are then rad/s² per unit of normalised thrust
difference (``a_k (P s)_k``: ω̇ when one rotor pair gives full thrust more than the other), its
rotor-rate term (yaw spin-up) rad/s² per (normalised speed)/s; the rates and their decay keep
rad/s and 1/s. No rotor speed in rad/s is known: where a result names ``rad_s_per_rpm`` for a
command-driven rotation, read it as this scale, not a conversion.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from droneid.errors import DataError
from droneid.simulation.motor_model import MotorModel
from droneid.simulation.openloop import StateLog

__all__ = ["CommandSpeeds", "COMMAND_SPEED_NOTE"]

#: what the rotational model's rotor "speeds" are on a command-driven vehicle (the result's speed_note)
COMMAND_SPEED_NOTE = ("motor commands through the identified motor model: each rotor's normalised speed "
                      "w = sqrt(f_e(q)) (0..1 of full speed, through the motor lag where one was kept), so "
                      "s = w² is the rotor's thrust as a fraction of full thrust (the commands' normalised "
                      "thrust units, not rad/s); torque coefficients in rad/s² per unit of normalised thrust")


@dataclass(frozen=True)
class CommandSpeeds:
    """The rotors' normalised speeds of a command-driven vehicle (see the module docstring).

    motor : the identified :class:`MotorModel` (curve, compensation, lag)
    motors : the number of per-motor commands ``motor1..motorN`` (the layout's rotors)
    offset_s : the plan's offset of the commands (s; they are read at ``t − offset_s``) where no
        lag was kept; with a lag they are read at t (the lag is the model of their lead)
    """
    motor: MotorModel
    motors: int
    offset_s: float = 0.0

    @classmethod
    def from_record(cls, config: Mapping) -> "CommandSpeeds | None":
        """The command speeds of a result.json ``config`` (or a plan's record) whose prior reads
        per-motor commands (``source`` ``motor``), or None (motor speeds, a collective throttle:
        no per-rotor command)."""
        motor = MotorModel.from_record(config)
        params = dict(config.get("prior_params") or {})
        if motor is None or params.get("source") != "motor":
            return None
        n = int(params.get("motors") or 0)
        delays = dict(config.get("delays_s") or {})
        return cls(motor, n, float(delays.get("motor1", 0.0))) if n else None

    def to_dict(self) -> dict:
        """JSON-able: the motor model's fields, the motor count and the offset."""
        m = self.motor
        return {"expo": float(m.expo), "spin": [float(v) for v in m.spin], "v_ref": m.v_ref,
                "lag_s": float(m.lag_s), "motors": int(self.motors), "offset_s": float(self.offset_s)}

    @classmethod
    def from_dict(cls, d: Mapping) -> "CommandSpeeds":
        try:
            v_ref = d.get("v_ref")
            motor = MotorModel(float(d["expo"]), tuple(float(v) for v in d["spin"]),
                               None if v_ref is None else float(v_ref), float(d.get("lag_s") or 0.0))
            return cls(motor, int(d["motors"]), float(d.get("offset_s") or 0.0))
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(f"the rotational model's command record is damaged: {exc}") from None

    def signals(self) -> tuple[str, ...]:
        """The logged inputs read: ``motor1..N`` and, where the compensation was kept, ``battery_voltage``."""
        return (*(f"motor{i}" for i in range(1, self.motors + 1)),
                *(("battery_voltage",) if self.motor.v_ref is not None else ()))

    def offset_steps(self, dt_s: float) -> int:
        """Whole grid steps the commands are read back (0 through a lag)."""
        return 0 if self.motor.lagged else int(round(self.offset_s / dt_s))

    def speeds(self, log: StateLog) -> np.ndarray:
        """(N, motors) normalised rotor speeds w (0..1) of ``log``'s commands (see the module docstring)."""
        u = np.column_stack([log.column(f"motor{i}") for i in range(1, self.motors + 1)])
        volts = log.column("battery_voltage") if self.motor.v_ref is not None else None
        if not self.motor.lagged:
            idx = np.clip(np.arange(len(log)) - self.offset_steps(log.dt_s), 0, len(log) - 1)
            u, volts = u[idx], None if volts is None else volts[idx]
        return self.motor.speeds(u, volts, log.dt_s)

    def speed_log(self, log: StateLog) -> StateLog:
        """``log`` with its rotor speeds (``rpm``) the normalised speeds :meth:`speeds`."""
        return replace(log, rpm=self.speeds(log))

    def text(self) -> str:
        """In words, for the result and the exported file."""
        offset = (f"; without a lag the commands are read at t − {1000 * self.offset_s:.0f} ms (the plan's offset)"
                  if not self.motor.lagged and self.offset_s else "")
        return f"the {self.motors} motor commands through the identified motor model: {self.motor.text()}{offset}"
