"""identify's rotational stage (issue 28): the body-rate targets ω̇x, ω̇y, ω̇z of the whole vehicle.

From the training flights only, :func:`choose_rotation` (as identify's :class:`RotationJob`)

1. reads each flight's full state (position, velocity, attitude quaternion, body rates) and motor
   speeds onto one grid, in-flight stretches clear of gaps and screened samples only
   (:func:`droneid.simulation.openloop.flight_state_logs`);
2. takes the rotor layout from ``--frame`` or, failing that, identifies it from the data as a
   torque sign pattern (:func:`droneid.rotation.model.identify_layout`) and names the known layout
   (:data:`priors.torque.LAYOUTS`) it matches;
3. chooses the rotational model by leave-one-flight-out open-loop validation
   (:func:`droneid.rotation.choice.select_rotation`): each candidate against the **empirical
   baseline of rotation, the nominal rigid body with the body rates held** (ω̇ = 0, the
   benchmark's Physics row);
4. gives each axis a verdict: the body-rate SimErr of that axis (Σ_{h=1..50} mean |Δω_k|, rad/s)
   of the chosen model against the rates held, in validation and, where there are test flights,
   on them (open loop, with identify's final v̇ models as the translation).

The test flights never take part in a choice: they are scored after it. Rates in rad/s, angular
accelerations in rad/s², motor speeds converted to rad/s by their recorded unit (``rpm``: 2π/60;
``erpm``: the Crazyflie 2.1 Brushless's 6 electrical rpm per mechanical revolution, said in the
result: the model's coefficients scale with it, its predictions do not). A command-driven vehicle
(no rotor speeds; issue 36) runs the same stage on each rotor's normalised speed from its command
through the plan's motor model (:mod:`droneid.rotation.commands`): its torque inputs are then the
rotors' thrusts as fractions of full thrust, not rad/s, as the result's ``speed_note`` says.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from priors.torque import LAYOUTS, get_layout

from droneid.errors import DataError, DroneIdError
from droneid.core.io_util import to_jsonable
from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM, IdentifiedTranslation, IdentifiedVehicle, StateLog, flight_state_logs
from droneid.fitting.verdict import Verdict, axis_verdict
from droneid.rotation.commands import COMMAND_SPEED_NOTE, CommandSpeeds
from droneid.simulation.motor_model import MotorModel
from droneid.rotation.model import (AXIS_NAMES, NO_RESPONSE, SPEED_UNIT, RotationModel, identify_layout,
                                    unsteerable)
from droneid.rotation.choice import DEFAULT_CANDIDATES, HeldRates, select_rotation, validation_sums
from droneid.rotation.gains import TorqueGains, check_gains, torque_gains

__all__ = ["ROTATION_TARGETS", "AxisResult", "RotationResult", "RotationJob", "rotation_job", "choose_rotation",
           "score_rotation", "speed_scale"]

#: the rotational targets, body FLU axes x (roll), y (pitch), z (yaw)
ROTATION_TARGETS = ("wx_dot", "wy_dot", "wz_dot")
#: the unit of the torque gains of logged rotor speeds, and of a command-driven vehicle's
GAIN_UNIT = "rad/s² per unit of (P s), s = (rotor speed / 1000 rad/s)²"
GAIN_UNIT_COMMANDS = "rad/s² per unit of (P s), s = each rotor's thrust as a fraction of full thrust"


@dataclass(frozen=True)
class AxisResult:
    """One rotational target: the rung its ladder took (:data:`droneid.rotation.choice.RUNGS`:
    held, damping, torque), its body-rate SimErr (Σ_h mean |Δω_k|, rad/s) with the rates held (the
    empirical baseline) and with the chosen model, in validation (held-out training flights) and on
    the test flights (NaN without any), and the verdict."""
    target: str
    rung: str
    validation_held: float
    validation_model: float
    test_held: float
    test_model: float
    verdict: str
    verdict_kind: str

    def to_dict(self) -> dict:
        return to_jsonable({"target": self.target, "rung": self.rung, "validation": {"held": self.validation_held,
                                                                  "model": self.validation_model},
                            "test": {"held": self.test_held, "model": self.test_model},
                            "verdict": self.verdict, "verdict_kind": self.verdict_kind})

    @classmethod
    def from_dict(cls, d: Mapping) -> "AxisResult":
        def num(v):
            return math.nan if v is None else float(v)
        return cls(str(d["target"]), str(d["rung"]), num(d["validation"]["held"]), num(d["validation"]["model"]),
                   num(d["test"]["held"]), num(d["test"]["model"]), str(d["verdict"]), str(d["verdict_kind"]))


@dataclass(frozen=True)
class RotationResult:
    """result.json's ``rotation`` (docs/result-json.md).

    layout, layout_source : the rotor layout used and where it came from
    rad_s_per_rpm : the motor speeds' conversion to rad/s, and ``speed_note`` why
    model : the chosen rotational model, or None (rates held: no candidate beat them in validation)
    choice : :meth:`droneid.rotation.choice.RotationChoice.to_dict` without its model (every
        candidate's validation, the chosen rungs, each axis's ladder)
    axes : one :class:`AxisResult` per rotational target
    open_loop_test : the benchmark's metric on the test flights ({} without any):
        :func:`droneid.use.predict.open_loop_section`'s document
    notes : sentences
    dt_s : the grid step (s) of the training flights' state logs: the step the model's delays and
        time constants were fitted at (the exported step function's default step)
    from_commands : the rotors' speeds came from the logged motor commands through the plan's motor
        model (:mod:`droneid.rotation.commands`: ``s`` in units of full thrust), not logged speeds
    torque_gains : the vehicle's torque gains per body axis, with intervals and their constancy
        across the training flights (:mod:`droneid.rotation.gains`), whatever rung each axis took;
        None when they could not be fitted (a note says why)
    """
    layout: str
    layout_source: str
    rad_s_per_rpm: float
    speed_note: str
    model: RotationModel | None
    choice: Mapping[str, object]
    axes: tuple[AxisResult, ...]
    open_loop_test: Mapping[str, object] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    dt_s: float = math.nan
    from_commands: bool = False
    torque_gains: TorqueGains | None = None

    def to_dict(self) -> dict:
        return to_jsonable({"targets": list(ROTATION_TARGETS), "layout": self.layout,
                            "layout_source": self.layout_source, "rad_s_per_rpm": self.rad_s_per_rpm,
                            "speed_note": self.speed_note,
                            "model": None if self.model is None else self.model.to_dict(),
                            "choice": dict(self.choice), "axes": [a.to_dict() for a in self.axes],
                            "open_loop_test": dict(self.open_loop_test), "notes": list(self.notes),
                            "dt_s": self.dt_s, "from_commands": self.from_commands,
                            "torque_gains": None if self.torque_gains is None else self.torque_gains.to_dict()})

    @classmethod
    def from_dict(cls, d: Mapping) -> "RotationResult":
        """Read back :meth:`to_dict` (DataError naming what is missing)."""
        try:
            model = None if d.get("model") is None else RotationModel.from_dict(d["model"])
            return cls(str(d["layout"]), str(d["layout_source"]), float(d["rad_s_per_rpm"]),
                       str(d.get("speed_note") or ""), model, dict(d["choice"]),
                       tuple(AxisResult.from_dict(a) for a in d["axes"]), dict(d.get("open_loop_test") or {}),
                       tuple(d.get("notes") or ()), math.nan if d.get("dt_s") is None else float(d["dt_s"]),
                       bool(d.get("from_commands", False)),
                       None if d.get("torque_gains") is None else TorqueGains.from_dict(d["torque_gains"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(f"the result's rotation section is damaged: {exc}") from None


def speed_scale(flight) -> tuple[float, str]:
    """(rad/s per logged motor-speed unit, why) from the recorded unit of ``rpm1``; DataError
    when the motor signals are not speeds (commands, duty cycles)."""
    if "rpm1" not in flight:
        raise DataError(f"{flight.name}: the rotational model needs per-motor rotor speeds (rpm1..), "
                        f"which the log lacks")
    unit = flight["rpm1"].unit
    if unit == "rpm":
        return 2.0 * math.pi / 60.0, "motor speeds in rpm: 2π/60 rad/s per rpm"
    if unit == "erpm":
        return CRAZYFLIE_RAD_S_PER_ERPM, ("motor speeds in electrical rpm, converted with 6 electrical "
                                          "rpm per mechanical revolution (Crazyflie 2.1 Brushless); the "
                                          "coefficients scale with it (the torque gains with its square), "
                                          "the predictions do not")
    raise DataError(f"{flight.name}: the rotational model needs rotor speeds (rpm1..); "
                    f"rpm1 is in {unit or 'no unit'}")


def _layout(logs: Sequence[StateLog], frame: str, rad_s_per_rpm: float) -> tuple[str, str]:
    """(layout name, where it came from): ``frame`` when given, else the known layout whose torque
    sign pattern the training data show."""
    if frame != "auto":
        return get_layout(frame).name, "--frame"
    signs, _ = identify_layout(logs, rad_s_per_rpm=rad_s_per_rpm)
    for name, lay in LAYOUTS.items():
        if lay.motors == signs.shape[1] and np.array_equal(np.sign(lay.patterns()), signs):
            shown = "; ".join(f"{ax} {''.join('+' if s > 0 else '−' for s in row)}"
                              for ax, row in zip(("roll", "pitch", "yaw"), signs))
            return name, f"identified from the training flights' torque signs ({shown})"
    raise DataError("the training flights' torque sign pattern matches no known rotor layout "
                    f"({', '.join(LAYOUTS)}); name it with --frame")


def choose_rotation(train_flights: Sequence, frame: str = "auto", commands: CommandSpeeds | None = None
                    ) -> RotationResult:
    """The choice, from the training flights only (see the module docstring): the layout, the
    rotational model and each axis's validation verdict (its test figures NaN). DataError when
    the flights cannot give a rotational model (missing signals, fewer than two training flights,
    a layout that matches none)."""
    return rotation_job(train_flights, frame, commands)._choose()


def rotation_job(train_flights: Sequence, frame: str = "auto", commands: CommandSpeeds | None = None) -> "RotationJob":
    """The rotational choice as a job (:class:`RotationJob`): the training flights' state logs and
    their motor-speed unit, checked here (DataError: missing signals, fewer than two training
    flights with an in-flight stretch). ``commands``: a command-driven vehicle's rotor speeds from
    its commands through the plan's motor model (:mod:`droneid.rotation.commands`; the rotational
    model then reads ``s`` in units of full thrust, not rad/s)."""
    if commands is not None:
        logs = flight_state_logs(train_flights, signals=commands.signals())
        train, scale, why = tuple(commands.speed_log(log) for log in logs), SPEED_UNIT, \
            f"{COMMAND_SPEED_NOTE}; {commands.text()}"
    else:
        scales = {speed_scale(f) for f in train_flights}
        if len(scales) > 1:
            raise DataError("the training flights log their motor speeds in different units ("
                            + "; ".join(sorted(w for _, w in scales)) + "): one rotational model cannot read both")
        scale, why = scales.pop()
        train = tuple(flight_state_logs(train_flights))
    if len({log.name for log in train}) < 2:
        raise DataError("the rotational model is chosen by holding each training flight out in turn: "
                        "it needs at least two training flights with an in-flight stretch (the torque gains, "
                        "which come with it, are not reported either)")
    return RotationJob(train, scale, why, frame, commands=commands)


def score_rotation(rot: RotationResult, test_flights: Sequence, translation: Mapping,
                   motor: MotorModel | None = None) -> RotationResult:
    """``rot`` with each axis's test figures and verdict: the body-rate SimErr per axis on the
    test flights, open loop with identify's final v̇ models {"vx_dot", "vy_dot", "vz_dot":
    IdentifiedModel} as the translation (``motor``: the motor model of a command-driven vehicle's
    models), against the rates held (a note when they cannot be scored)."""
    commands = None if rot.model is None else rot.model.commands
    try:
        tr = IdentifiedTranslation(translation, motor if motor is not None or commands is None else commands.motor)
        signals = tuple(dict.fromkeys([*tr.signals(), *(commands.signals() if commands is not None else ())]))
        test = flight_state_logs(test_flights, signals=signals)
        held = _axis_simerr(IdentifiedVehicle(tr, HeldRates()), test)
        model = _axis_simerr(IdentifiedVehicle(tr, rot.model), test) if rot.model is not None else held
    except DroneIdError as exc:
        return replace(rot, notes=(*rot.notes, f"rotation not scored on the test flights: {exc}"))
    rot = replace(rot, axes=_axes(rot.choice, [a.validation_model for a in rot.axes], held, model, rot.model))
    return _check_gains(rot, test_flights)


def _check_gains(rot: RotationResult, test_flights: Sequence) -> RotationResult:
    """``rot`` with its torque gains checked on the test flights (:func:`check_gains`; their own
    read of the flights: a command-driven vehicle's needs its command signals), or a note why not."""
    gains = rot.torque_gains
    if gains is None or gains.model is None:
        return rot
    try:
        signals = gains.model.commands.signals() if gains.model.commands is not None else ()
        return replace(rot, torque_gains=check_gains(gains, flight_state_logs(test_flights, signals=signals)))
    except DroneIdError as exc:
        return replace(rot, notes=(*rot.notes, f"the torque gains not checked on the test flights: {exc}"))


@dataclass(frozen=True)
class RotationJob:
    """:func:`choose_rotation` as a job of :func:`droneid.engine.runner.run_jobs`, beside identify's SNGP
    runs (it needs none of their results): the training flights' in-flight state logs, the motor
    speeds' rad/s per logged unit and why, and ``frame``. :meth:`run` returns the
    :class:`RotationResult`."""
    train: tuple[StateLog, ...]
    rad_s_per_rpm: float
    speed_note: str
    frame: str = "auto"
    target: str = "rotation"
    commands: CommandSpeeds | None = None

    def run(self) -> RotationResult | str:
        """The :class:`RotationResult`, or the one-line reason the flights cannot give one (a
        layout that matches none, no stretch long enough: a note of the result, not a failed job)."""
        try:
            return self._choose()
        except DroneIdError as exc:
            return str(exc)

    def _choose(self) -> RotationResult:
        train = list(self.train)
        layout, source = _layout(train, self.frame, self.rad_s_per_rpm)
        choice = select_rotation(train, layout, rad_s_per_rpm=self.rad_s_per_rpm)
        if choice.model is not None and self.commands is not None:    # it reads the commands' speeds
            choice = replace(choice, model=replace(choice.model, commands=self.commands))
        record = {k: v for k, v in choice.to_dict().items() if k != "model"}   # the model is kept once
        val_model = choice.table[choice.chosen]["rates_axis_simerr"] if choice.model is not None else \
            choice.held["rates_axis_simerr"]
        gains, notes = None, ()
        try:
            gains = torque_gains(train, get_layout(layout), DEFAULT_CANDIDATES[0], rad_s_per_rpm=self.rad_s_per_rpm,
                                 unit=GAIN_UNIT_COMMANDS if self.commands is not None else GAIN_UNIT,
                                 commands=self.commands)
        except DataError as exc:
            notes = (f"the torque gains could not be fitted: {exc}",)
        return RotationResult(layout, source, self.rad_s_per_rpm, self.speed_note, choice.model, record,
                              _axes(record, val_model, [math.nan] * 3, [math.nan] * 3, choice.model), notes=notes,
                              dt_s=float(np.median([log.dt_s for log in train])),
                              from_commands=self.commands is not None, torque_gains=gains)


def _axes(record: Mapping, val_model: Sequence[float], test_held: Sequence[float],
          test_model: Sequence[float], model: RotationModel | None) -> tuple[AxisResult, ...]:
    """Each rotational target's :class:`AxisResult` and verdict from the choice's record (its
    rungs, the held rates' validation SimErr per axis, its ladders) and the chosen model's
    validation and test SimErr per axis (rad/s; NaN: not scored); the verdict of an axis of
    ``model`` that does not answer the motors (decay-only or held) says so."""
    out = []
    stuck = unsteerable(model)
    for k, target in enumerate(ROTATION_TARGETS):
        rung, val_held = record["axis_choice"][k], record["held"]["rates_axis_simerr"][k]
        v: Verdict = axis_verdict(target, rung, val_held, val_model[k], test_held[k], test_model[k],
                                  why_held=_why_held(record["ladder"][k]))
        text = v.text + (f"; {NO_RESPONSE}" if AXIS_NAMES[k] in stuck else "")
        out.append(AxisResult(target, rung, val_held, val_model[k], test_held[k], test_model[k], text, v.kind))
    return tuple(out)


def _why_held(ladder: Mapping) -> str:
    """Why an axis could not leave ``held`` whatever the data said: too few (held-out flight,
    regime) cells for any step to reach the first threshold of Holm's order, ``alpha /
    family_size`` (a sign-flip p over B cells is at least 2^-B); "" when some step could have
    passed."""
    steps = ladder.get("steps") or ()
    alpha = float(ladder.get("alpha", 0.01))
    family = int(ladder.get("family_size", 1))
    first = alpha / family
    if not steps or any(2.0 ** -int(st.get("cells", 0)) < first for st in steps):
        return ""
    need = math.floor(math.log2(1.0 / first)) + 1
    most = max(int(st.get("cells", 0)) for st in steps)
    return (f"with {len(ladder.get('flights') or ())} held-out training flight(s) no rung can pass the test "
            f"({most} flight-regime cells: a sign-flip p is at least 2^-{most}, and the first step of Holm's "
            f"order needs p < α/{family} = {first:.2g}, so at least {need} cells)")


def _axis_simerr(model, logs: Sequence[StateLog]) -> list[float]:
    """Per body axis Σ_{h=1..50} mean |Δω_k| (rad/s) of ``model`` open loop over every start of
    ``logs`` (their in-flight parts)."""
    n, sums = validation_sums(model, logs, stride=1)
    if n == 0:
        raise DataError("no test flight has an in-flight stretch longer than 50 steps")
    return [float(v) for v in sums[2:] / n]
