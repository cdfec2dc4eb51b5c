"""A rigid-body model of the whole vehicle from its motor speeds, identified by robust least
squares, for open-loop simulation (:mod:`droneid.simulation.openloop`) (issue 28).

The rotational model is chosen per body axis by :func:`droneid.rotation.choice.select_rotation`
(leave-one-flight-out open-loop validation on training flights only): each axis holds its rate,
decays it (``ω̇_k = −c_k ω_k``: the closed loop stopping a rotation), is pulled back to level
(roll and pitch, the term ``attitude`` below: the attitude controller) or takes the torque model,
a rung being taken by :mod:`droneid.fitting.decide`'s calibrated rule over the (held-out flight, regime of
calm to hard flight) cells. It steps with a translational model in
:class:`droneid.simulation.openloop.IdentifiedVehicle`; :func:`droneid.use.vehicle_export.export_vehicle` writes it as
Python or C. On the shared Crazyflie squares the torque model is the best pooled, but worse than
the simpler rungs in their calm windows, and the choice refuses it; the spring it takes for roll
and pitch does not transfer in full to the melon runs (see docs/use-the-model.md).

Rotation (body FLU, per axis ``k`` = roll, pitch, yaw; ``s_i = (ω_i / 1000 rad/s)²`` with ``ω_i``
the rotor speeds ``d`` steps earlier, ``P`` the layout's torque patterns, :mod:`priors.torque`)::

    ω̇_k = a_k (P s)_k + e_k Σ s_i − c_k ω_k + γ_k (ω × ω)_k-term + r_k (P ω̇_rotor)_yaw + b_k

* ``a_k (P s)_k``: torque from thrust differences (roll, pitch) and rotor drag (yaw), over inertia;
* ``e_k Σ s_i``: the collective thrust acting about an offset centre (centre of gravity away from
  the geometric centre, unequal rotors): it scales with thrust, which a constant trim cannot;
* ``c_k ω_k``: rate damping (rotor flapping, drag); ``γ_k``: gyroscopic ``ω_j ω_l`` terms, e.g.
  ``ω̇x ∋ (J_y − J_z)/J_x · ω_y ω_z``; ``r_k`` (yaw only): reaction to the rotors' spin-up;
* ``b_k``: trim. It is fitted per training flight; a new flight gets their mean.
* ``−κ_k (θ_k − θ0_k)`` (term ``attitude``, roll and pitch; ``θ`` the Z-Y-X roll and pitch
  angles of the attitude, ``θ0`` the training flights' median ``level_rad``): the closed loop's
  attitude controller pulling the vehicle back to its level attitude. With ``damping`` it is the
  closed-loop spring-damper of a vehicle whose controller holds it level (a model of the vehicle
  with its controller, not of the rigid body: it reads no motor speed);
* ``h_k v_b`` (term ``rotor_drag``, roll and pitch): the rotors' drag moment (blade flapping):
  a body velocity ``v_b`` pitches the vehicle back against it, ``ω̇x ∋ +h v_by``,
  ``ω̇y ∋ −h v_bx``; ``rotor_drag_thrust`` adds ``h' v_b (Σ s_i)`` (the moment grows with thrust).
  On the shared Crazyflie flights the onboard controller holds this moment with slow thrust
  differences (their low-frequency part is ``≈ −0.35 v_b`` on squares and melon alike): without
  the term those differences read as torques that never turn the vehicle.

The trim of a new flight (``balance_weight_s``): every flight has its own balance point (centre of
gravity, battery, propellers); the controller keeps the mean torque at zero, so the mean of the
torque inputs since the flight began (:func:`balanced`, causal, started from the training mean
with ``balance_weight_s`` seconds of weight) estimates it. The model then reads motor speeds from
before the prediction window (never states): say so where its figures are compared with models
that read the window only.

The balance point of the torque inputs moves between flights (battery and centre of gravity: on
the shared Crazyflie squares the hover pitch pattern ``(P s)_pitch`` of runs 1-2 differs from
that of runs 3-5, and so do their pitch trims). With ``centre_tau_s`` the torque inputs are
taken about their causal moving average (:func:`centred`): the model then uses motor speeds from
before the prediction window, which the benchmark's own models do not.

Translation (world ENU)::

    v̇ = R(q) e_z · k_T Σ s_i − g e_z − R D Rᵀ v,   D = diag(d_x, d_y, d_z) ≥ 0, g = 9.81 fixed

Targets ``v̇`` and ``ω̇`` come from the logged velocity and body rates by the Savitzky-Golay
differentiator of :mod:`droneid.core.differentiation`; rows where a motor is stopped or the vehicle is
near the ground are screened out. Fits are Huber IRLS (:func:`droneid.core.regression.robust_fit`).
"""
from __future__ import annotations

from collections.abc import Sequence
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from priors.torque import RotorLayout, get_layout

from droneid.core.differentiation import get_differentiator
from droneid.errors import DataError
from droneid.core.frames import quat_to_euler, quat_to_matrix
from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM, G, IdentifiedVehicle, StateLog
from droneid.core.regression import robust_fit, robust_fit_grouped
from droneid.rotation.commands import CommandSpeeds

__all__ = ["RotationModel", "TranslationModel", "VehicleModel", "fit_rotation", "fit_translation",
           "fit_vehicle", "identify_layout", "flying_mask", "flying_segments", "centred", "smoothed",
           "derivative", "spin_rate", "ROTATION_TERMS", "KNOWN_TERMS", "CLOSED_LOOP_TERMS", "balanced",
           "body_velocity", "tilt", "translation_rows", "fit_translation_rows", "segment_bounds", "SPEED_UNIT",
           "AXIS_NAMES", "NO_RESPONSE"]

#: optional rotational terms (besides the torque pattern and the trim)
ROTATION_TERMS = ("centre", "damping", "gyro", "spinup")
#: every optional rigid-body term :func:`fit_rotation` knows
KNOWN_TERMS = ROTATION_TERMS + ("rotor_drag", "rotor_drag_thrust")
#: closed-loop terms: the vehicle with its controller (``attitude``: pulled back to level)
CLOSED_LOOP_TERMS = ("attitude",)
#: roll gets +v_by, pitch −v_bx (the rotor drag moment opposes the body velocity)
_DRAG_AXIS = ((1, 1.0), (0, -1.0))
SPEED_UNIT = 1000.0  # rad/s: s_i = (ω_i / 1000 rad/s)², coefficients near one


def _delayed(a: np.ndarray, d: int) -> np.ndarray:
    """``a`` delayed by ``d`` >= 0 samples, the first value held before the log starts."""
    if d <= 0:
        return a
    return np.concatenate([np.repeat(a[:1], d, axis=0), a[:-d]], axis=0)


def spin_rate(om: np.ndarray, dt_s: float) -> np.ndarray:
    """Rotor speed rates (…/s) by backward differences: causal, so that a prediction from ``t``
    uses no input after the step it simulates (zero at the first sample)."""
    out = np.zeros_like(om)
    out[1:] = np.diff(om, axis=0) / dt_s
    return out


def derivative(log: StateLog, cols: slice | np.ndarray, window_s: float) -> np.ndarray:
    """Time derivative of state columns (or of an (N, K) array) by Savitzky-Golay over
    ``window_s`` seconds, column by column."""
    x = log.state[:, cols] if isinstance(cols, slice) else np.asarray(cols, float)
    d = get_differentiator("savgol", window_s=window_s)
    return np.column_stack([d(x[:, k], log.t_s) for k in range(x.shape[1])])


def flying_mask(log: StateLog, min_height_m: float = 0.1) -> np.ndarray:
    """Rows fit for training: every motor turning and the vehicle above ``min_height_m``."""
    return np.all(log.rpm > 0, axis=1) & (log.state[:, 2] > min_height_m)


def flying_segments(log: StateLog, min_steps: int = 100) -> list[StateLog]:
    """The stretches of a log where :func:`flying_mask` holds, as logs of their own (at least
    ``min_steps`` samples each): validation scores windows in flight only."""
    return [StateLog(f"{log.name}[{a}:{b}]", log.t_s[a:b], log.state[a:b], log.rpm[a:b], log.dt_s)
            for a, b in segment_bounds(log, min_steps)]


def segment_bounds(log: StateLog, min_steps: int) -> list[tuple[int, int]]:
    m = flying_mask(log).astype(int)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], m, [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2]) if b - a >= min_steps]


def centred(s: np.ndarray, dt_s: float, tau_s: float | None) -> np.ndarray:
    """``s`` minus its causal exponential moving average (time constant ``tau_s`` seconds, the
    first sample as its start): the torque inputs about the flight's own balance point, from past
    motor speeds only. ``tau_s=None``: ``s`` unchanged."""
    if tau_s is None:
        return s
    return s - smoothed(s, dt_s, tau_s)


def smoothed(x: np.ndarray, dt_s: float, tau_s: float | None) -> np.ndarray:
    """Causal first-order low-pass (exponential moving average) of ``x`` (N, …) along time,
    time constant ``tau_s`` seconds, started at the first sample. ``tau_s=None``: ``x``."""
    if tau_s is None:
        return x
    from scipy.signal import lfilter
    a = min(1.0, dt_s / float(tau_s))
    return lfilter([a], [1.0, a - 1.0], x, axis=0, zi=(1.0 - a) * x[:1])[0]


def balanced(s: np.ndarray, dt_s: float, prior: np.ndarray | None, weight_s: float | None) -> np.ndarray:
    """``s`` (N, M) minus its mean since the first sample, causal: ``(Σ_{j≤i} s_j dt + w·prior)
    / (i·dt + w)`` with the prior mean ``prior`` (M,) weighted as ``weight_s`` seconds of data.
    ``weight_s=None``: ``s`` unchanged."""
    if weight_s is None:
        return s
    n = dt_s * np.arange(1, s.shape[0] + 1)[:, None]
    prior = np.zeros(s.shape[1]) if prior is None else np.asarray(prior, float)
    return s - (np.cumsum(s, axis=0) * dt_s + float(weight_s) * prior) / (n + float(weight_s))


def body_velocity(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Velocity (W, 3) in the body frame FLU, m/s, from the attitude ``q`` and world ENU ``v``."""
    return np.einsum("nji,nj->ni", quat_to_matrix(q), v)


def _mid(a: np.ndarray) -> np.ndarray:
    """Values at the step midpoints: the mean of consecutive samples (one row fewer)."""
    return 0.5 * (a[1:] + a[:-1])


def _speeds(log: StateLog, rad_s_per_rpm: float) -> np.ndarray:
    return log.rpm * (rad_s_per_rpm / SPEED_UNIT)


# -- rotation ------------------------------------------------------------------------------------
def tilt(q: np.ndarray) -> np.ndarray:
    """Roll and pitch (W, 2) in rad, Z-Y-X, of the attitude quaternions ``q`` (W, 4)."""
    roll, pitch, _ = quat_to_euler(q)
    return np.stack([roll, pitch], axis=-1)


def _rotation_named(k: int, P: np.ndarray, s: np.ndarray, w: np.ndarray, rates,
                    terms: tuple[str, ...], vb: np.ndarray | None = None,
                    att: np.ndarray | None = None) -> list[tuple[str, np.ndarray]]:
    """(name, column) of axis ``k``'s regressors, in the order of its coefficients; ``att`` (W, 2)
    the roll and pitch about the level attitude (rad), for the term ``attitude``."""
    unknown = [t for t in terms if t not in KNOWN_TERMS + CLOSED_LOOP_TERMS]
    if unknown:
        raise DataError(f"unknown rotational term(s) {', '.join(unknown)}; known: "
                        f"{', '.join(KNOWN_TERMS + CLOSED_LOOP_TERMS)}")
    cols = [("pattern", s @ P[k])]
    if "centre" in terms:
        cols.append(("centre", s.sum(axis=-1)))
    if "damping" in terms:
        cols.append(("damping", -w[:, k]))
    if "gyro" in terms:
        i, j = [(1, 2), (2, 0), (0, 1)][k]
        cols.append(("gyro", w[:, i] * w[:, j]))
    if "spinup" in terms and k == 2:
        cols.append(("spinup", rates @ P[2]))
    if k < 2 and ("rotor_drag" in terms or "rotor_drag_thrust" in terms):
        if vb is None:
            raise DataError("the rotor drag moment needs the body velocity")
        j, sign = _DRAG_AXIS[k]
        if "rotor_drag" in terms:
            cols.append(("rotor_drag", sign * vb[:, j]))
        if "rotor_drag_thrust" in terms:
            cols.append(("rotor_drag_thrust", sign * vb[:, j] * s.sum(axis=-1)))
    if k < 2 and "attitude" in terms:
        if att is None:
            raise DataError("the attitude term needs the roll and pitch angles")
        cols.append(("attitude", -att[:, k]))
    return cols


def _rotation_columns(k: int, P: np.ndarray, s: np.ndarray, w: np.ndarray, rates,
                      terms: tuple[str, ...], vb: np.ndarray | None = None,
                      att: np.ndarray | None = None) -> list[np.ndarray]:
    return [c for _, c in _rotation_named(k, P, s, w, rates, terms, vb, att)]


@dataclass(frozen=True)
class RotationModel:
    """ω̇ (rad/s², body FLU) from the state and the rotor speeds; see the module docstring.

    ``coef[k]``: coefficients of axis ``k`` in the order of :func:`_rotation_columns`;
    ``trim`` (3,) rad/s²; ``delay_steps`` of the rotor speeds; ``layout`` the torque patterns.
    """
    layout: RotorLayout
    terms: tuple[str, ...]
    coef: tuple[np.ndarray, np.ndarray, np.ndarray]
    trim: np.ndarray
    delay_steps: int = 0
    rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM
    flight_trims: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    #: None, or the time constant (s) of :func:`centred` applied to ``s`` before the torque terms
    centre_tau_s: float | None = None
    #: None, or the time constant (s) of the causal low-pass (:func:`smoothed`) of the rotor speeds
    lowpass_tau_s: float | None = None
    #: None, or the prior weight (s) of :func:`balanced`: ``s`` about its mean since the flight began
    balance_weight_s: float | None = None
    #: the training flights' mean ``s`` (M,), the prior of :func:`balanced`
    balance_prior: np.ndarray | None = None
    #: the level attitude (roll, pitch) in rad of the term ``attitude`` (None: (0, 0))
    level_rad: np.ndarray | None = None
    #: a command-driven vehicle: its rotor speeds are the normalised speeds of its logged commands
    #: (:class:`droneid.rotation.commands.CommandSpeeds`; ``rad_s_per_rpm`` is then SPEED_UNIT and
    #: ``s`` the rotors' thrust as a fraction of full thrust); None: logged rotor speeds
    commands: CommandSpeeds | None = None

    def to_dict(self) -> dict:
        """JSON-able: the layout by name with its geometry, and every field as plain lists."""
        lay = self.layout
        return {"layout": {"name": lay.name, "x": list(lay.x), "y": list(lay.y), "spin": list(lay.spin),
                           "source": lay.source},
                "terms": list(self.terms), "coef": [np.asarray(c, float).tolist() for c in self.coef],
                "columns": [list(self.columns(k)) for k in range(3)],
                "trim": np.asarray(self.trim, float).tolist(), "delay_steps": int(self.delay_steps),
                "rad_s_per_rpm": float(self.rad_s_per_rpm),
                "flight_trims": np.asarray(self.flight_trims, float).tolist(),
                "centre_tau_s": self.centre_tau_s, "lowpass_tau_s": self.lowpass_tau_s,
                "balance_weight_s": self.balance_weight_s,
                "balance_prior": None if self.balance_prior is None else np.asarray(self.balance_prior, float).tolist(),
                "level_rad": None if self.level_rad is None else np.asarray(self.level_rad, float).tolist(),
                "commands": None if self.commands is None else self.commands.to_dict()}

    @classmethod
    def from_dict(cls, d: dict) -> "RotationModel":
        """The inverse of :meth:`to_dict`."""
        try:
            lay = d["layout"]
            layout = RotorLayout(lay["name"], tuple(lay["x"]), tuple(lay["y"]), tuple(lay["spin"]), lay.get("source", ""))
            prior, level = d.get("balance_prior"), d.get("level_rad")
            return cls(layout, tuple(d["terms"]), tuple(np.asarray(c, float) for c in d["coef"]),
                       np.asarray(d["trim"], float), int(d["delay_steps"]), float(d["rad_s_per_rpm"]),
                       np.asarray(d.get("flight_trims") or np.zeros((0, 3)), float).reshape(-1, 3),
                       d.get("centre_tau_s"), d.get("lowpass_tau_s"), d.get("balance_weight_s"),
                       None if prior is None else np.asarray(prior, float),
                       None if level is None else np.asarray(level, float),
                       None if d.get("commands") is None else CommandSpeeds.from_dict(d["commands"]))
        except (KeyError, TypeError, ValueError) as e:
            raise DataError(f"a rotation model record is damaged: {e}") from None

    def columns(self, k: int) -> tuple[str, ...]:
        """Names of axis ``k``'s terms in the order of ``coef[k]`` (``pattern``, ``centre``,
        ``damping``, ``gyro``, ``spinup``, ``rotor_drag``, ``rotor_drag_thrust``, ``attitude`` as
        present)."""
        m = self.layout.motors
        z = np.zeros((1, m))
        return tuple(n for n, _ in _rotation_named(k, self.layout.patterns(), z, np.zeros((1, 3)), z,
                                                   self.terms, np.zeros((1, 3)), np.zeros((1, 2))))

    #: the terms through which an axis answers the motor speeds
    MOTOR_TERMS = ("pattern", "centre", "spinup", "rotor_drag", "rotor_drag_thrust")

    def unsteerable_axes(self) -> tuple[str, ...]:
        """The body axes ("roll", "pitch", "yaw") whose ω̇ has no nonzero motor term: decay-only
        or held, they do not answer differential thrust, so a controller cannot steer them."""
        out = []
        for k, axis in enumerate(("roll", "pitch", "yaw")):
            coef = np.asarray(self.coef[k], float)
            if not any(n in self.MOTOR_TERMS and c != 0.0 for n, c in zip(self.columns(k), coef)):
                out.append(axis)
        return tuple(out)

    @property
    def input_width(self) -> int:
        """Columns of :meth:`inputs`: ``s`` and the rotor speed rates, one per rotor each."""
        return 2 * self.layout.motors

    def conditioned(self, rpm: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """``(s, rates)`` (N, M) each, from motor speeds ``rpm`` (N, M) as logged on a uniform grid
        of step ``dt_s``: delayed, low-passed, squared in (1000 rad/s)², centred and balanced as
        this model was fitted. Causal: row ``i`` reads ``rpm[:i + 1]`` only."""
        om = smoothed(_delayed(np.asarray(rpm, float) * (self.rad_s_per_rpm / SPEED_UNIT), self.delay_steps),
                      dt_s, self.lowpass_tau_s)
        s = balanced(centred(om ** 2, dt_s, self.centre_tau_s), dt_s, self.balance_prior, self.balance_weight_s)
        return s, spin_rate(om, dt_s)

    def inputs(self, log: StateLog) -> np.ndarray:
        """(N, 2M) for :func:`droneid.simulation.openloop.simulate`: :meth:`conditioned` side by side
        (of the logged rotor speeds, or of the commands' normalised speeds: :attr:`commands`)."""
        rpm = log.rpm if self.commands is None else self.commands.speeds(log)
        if rpm.shape[1] != self.layout.motors:
            raise DataError(f"{log.name}: the rotation model has {self.layout.motors} rotors, the log "
                            f"{rpm.shape[1]} motor speeds")
        return np.hstack(self.conditioned(rpm, log.dt_s))

    def signals(self) -> tuple[str, ...]:
        """The logged inputs besides the rotor speeds a state log must carry for :meth:`inputs`."""
        return () if self.commands is None else self.commands.signals()

    def ang_accel(self, state: np.ndarray, u: np.ndarray) -> np.ndarray:
        """ω̇ (W, 3) from the state (W, 13) and a row of :meth:`inputs` (W, 2M)."""
        m = self.layout.motors
        vb = body_velocity(state[:, 6:10], state[:, 3:6])
        att = self.about_level(state[:, 6:10]) if "attitude" in self.terms else None
        return self.ang_accel_from(state[:, 10:13], u[:, :m], u[:, m:2 * m], vb, att)

    def about_level(self, q: np.ndarray) -> np.ndarray:
        """Roll and pitch (W, 2) in rad of the attitudes ``q`` (W, 4) about ``level_rad``."""
        return tilt(q) - (np.zeros(2) if self.level_rad is None else np.asarray(self.level_rad, float))

    def ang_accel_from(self, w: np.ndarray, s: np.ndarray, rates: np.ndarray,
                       vb: np.ndarray | None = None, att: np.ndarray | None = None) -> np.ndarray:
        """ω̇ (W, 3) from body rates ``w`` (W, 3), ``s = (ω_i/1000)²``, rotor speed rates, (for
        the rotor drag moment) the body velocity ``vb`` (W, 3) in m/s and (for the term
        ``attitude``) the roll and pitch about the level ``att`` (W, 2) in rad."""
        P = self.layout.patterns()
        out = np.empty((w.shape[0], 3))
        for k in range(3):
            cols = _rotation_columns(k, P, s, w, rates, self.terms, vb, att)
            out[:, k] = np.column_stack(cols) @ self.coef[k] + self.trim[k]
        return out


def fit_rotation(logs: Sequence[StateLog], layout: RotorLayout | str = "crazyflie_x", *,
                 terms: tuple[str, ...] = ROTATION_TERMS, delay_steps: int = 0,
                 window_s: float = 0.05, rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM,
                 lowpass_tau_s: float | None = None, balance_weight_s: float | None = None,
                 centre_tau_s: float | None = None) -> RotationModel:
    """Fit ω̇ per axis on training flights by equation error (Huber IRLS), with one trim per
    flight (their mean is kept). Rows sit at the step midpoints (the input is held over the step)
    where every motor turns in flight. ``lowpass_tau_s``: causal low-pass of the rotor speeds;
    ``balance_weight_s``: torque inputs about their mean since the flight began (:func:`balanced`,
    the prior being the training flights' mean)."""
    layout = get_layout(layout) if isinstance(layout, str) else layout
    layout.check()
    P = layout.patterns()
    shell = RotationModel(layout, tuple(terms), (np.zeros(0),) * 3, np.zeros(3), int(delay_steps),
                          float(rad_s_per_rpm), lowpass_tau_s=lowpass_tau_s, centre_tau_s=centre_tau_s)
    if "attitude" in terms:
        flying = [tilt(log.state[flying_mask(log), 6:10]) for log in logs]
        if any(f.size for f in flying):
            shell = dataclasses.replace(shell, level_rad=np.median(np.concatenate(flying), axis=0))
    prior = None
    if balance_weight_s is not None:
        flying = [shell.conditioned(log.rpm, log.dt_s)[0][flying_mask(log)] for log in logs]
        if not any(f.size for f in flying):
            raise DataError("fit_rotation: no training row with every motor turning in flight")
        prior = np.concatenate(flying).mean(axis=0)
        shell = dataclasses.replace(shell, balance_weight_s=float(balance_weight_s), balance_prior=prior)
    rows = [rotation_rows(log, shell, window_s) for log in logs]
    if not any(r[0].any() for r in rows):
        raise DataError("fit_rotation: no training row with every motor turning in flight")
    n_f = len(logs)
    coef, trims = [], np.zeros((n_f, 3))
    groups = np.concatenate([np.full(int(r[0].sum()), j) for j, r in enumerate(rows)])
    for k in range(3):
        A = np.vstack([rotation_design(k, P, terms, r) for r in rows])
        y = np.concatenate([wd[m, k] for m, _, _, _, wd, _, _ in rows])
        lo = rotation_bounds(k, terms, A.shape[1])
        # one trim per flight: a free intercept per log (robust_fit_grouped: no one-hot columns)
        beta = robust_fit_grouped(A, y, groups, lo=lo).beta
        nc = A.shape[1]
        coef.append(beta[:nc])
        present = np.unique(groups)
        trims[present, k] = beta[nc:]
    return dataclasses.replace(shell, coef=tuple(coef), trim=trims.mean(axis=0), flight_trims=trims)


def rotation_rows(log: StateLog, shell: RotationModel, window_s: float) -> tuple[np.ndarray, ...]:
    """One log's rows of :func:`fit_rotation` with the input conditioning of ``shell``, at the step
    midpoints k + 1/2 (the input u_k is held over [k, k+1]): ``(mask, s, ω, rotor speed rates,
    ω̇, body velocity, roll and pitch about the level)``, the mask marking the rows in flight."""
    m = _mid(flying_mask(log).astype(float)) == 1.0
    s, rate = shell.conditioned(log.rpm, log.dt_s)
    wd = _mid(derivative(log, slice(10, 13), window_s))
    vb = _mid(body_velocity(log.state[:, 6:10], log.state[:, 3:6]))
    att = _mid(shell.about_level(log.state[:, 6:10]))
    return m, s[:-1], _mid(log.state[:, 10:13]), rate[:-1], wd, vb, att


def rotation_design(k: int, P: np.ndarray, terms: tuple[str, ...], rows: tuple[np.ndarray, ...],
                    s: np.ndarray | None = None) -> np.ndarray:
    """Axis ``k``'s design matrix (rows in flight, columns of :meth:`RotationModel.columns`) from
    :func:`rotation_rows`; ``s`` replaces the rows' conditioned inputs when given."""
    m, s0, w, sr, _, vb, att = rows
    s = s0 if s is None else s
    return np.column_stack(_rotation_columns(k, P, s[m], w[m], sr[m], terms, vb[m], att[m]))


def rotation_bounds(k: int, terms: tuple[str, ...], nc: int) -> np.ndarray:
    """Lower bounds of axis ``k``'s ``nc`` coefficients: the torque along the layout's pattern is a
    positive scale, damping never feeds energy in, the level attitude restores, never repels."""
    lo = np.full(nc, -np.inf)
    lo[0] = 0.0
    if "damping" in terms:
        lo[1 + ("centre" in terms)] = 0.0
    if k < 2 and "attitude" in terms:
        lo[nc - 1] = 0.0
    return lo


# -- translation ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class TranslationModel:
    """v̇ (m/s², world ENU) = R e_z k_T Σ s_i − g e_z − R diag(drag) Rᵀ v."""
    k_thrust: float
    drag: np.ndarray
    delay_steps: int = 0
    rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM
    g: float = G

    def to_dict(self) -> dict:
        """JSON-able fields."""
        return {"k_thrust": float(self.k_thrust), "drag": np.asarray(self.drag, float).tolist(),
                "delay_steps": int(self.delay_steps), "rad_s_per_rpm": float(self.rad_s_per_rpm), "g": float(self.g)}

    @classmethod
    def from_dict(cls, d: dict) -> "TranslationModel":
        """The inverse of :meth:`to_dict`."""
        try:
            return cls(float(d["k_thrust"]), np.asarray(d["drag"], float), int(d["delay_steps"]),
                       float(d["rad_s_per_rpm"]), float(d.get("g", G)))
        except (KeyError, TypeError, ValueError) as e:
            raise DataError(f"a translation model record is damaged: {e}") from None

    def inputs(self, log: StateLog) -> np.ndarray:
        """(N, M): ``s = (ω_i/1000 rad/s)²`` of the motor speeds ``delay_steps`` earlier."""
        return _delayed(_speeds(log, self.rad_s_per_rpm), self.delay_steps) ** 2

    def accel(self, state: np.ndarray, u: np.ndarray) -> np.ndarray:
        """v̇ (W, 3) from the state (W, 13) and a row of :meth:`inputs` (W, M)."""
        return self.accel_from(state[:, 6:10], state[:, 3:6], u)

    def accel_from(self, q: np.ndarray, v: np.ndarray, s: np.ndarray) -> np.ndarray:
        R = quat_to_matrix(q)
        a = R[:, :, 2] * (self.k_thrust * s.sum(axis=-1))[:, None]
        vb = np.einsum("nji,nj->ni", R, v) * self.drag
        a -= np.einsum("nij,nj->ni", R, vb)
        a[:, 2] -= self.g
        return a


def fit_translation(logs: Sequence[StateLog], *, delay_steps: int = 0, window_s: float = 0.05,
                    drag: bool = True, rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM
                    ) -> TranslationModel:
    """Fit ``k_T > 0`` and the body drag ``D ≥ 0`` on training flights (g fixed at 9.81)."""
    rows = [translation_rows(log, delay_steps=delay_steps, window_s=window_s, drag=drag,
                             rad_s_per_rpm=rad_s_per_rpm) for log in logs]
    return fit_translation_rows(rows, delay_steps=delay_steps, drag=drag, rad_s_per_rpm=rad_s_per_rpm)


def translation_rows(log: StateLog, *, delay_steps: int = 0, window_s: float = 0.05, drag: bool = True,
                     rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM) -> tuple[np.ndarray, np.ndarray] | None:
    """One log's least-squares rows of :func:`fit_translation`, ``(A, y)``, or None when it has no
    row in flight: computed once per log when several fits share the logs (blocked validation)."""
    # rows at the step midpoints k + 1/2: the input u_k is held over [k, k+1]
    m = _mid(flying_mask(log).astype(float)) == 1.0
    if not m.any():
        return None
    s = _delayed(_speeds(log, rad_s_per_rpm), delay_steps)[:-1][m] ** 2
    R = _mid(quat_to_matrix(log.state[:, 6:10]))[m]
    v = _mid(log.state[:, 3:6])[m]
    vb = np.einsum("nji,nj->ni", R, v)
    cols = [R[:, :, 2] * s.sum(axis=1)[:, None]]               # (n, 3) per thrust scale
    if drag:
        cols += [-R[:, :, j] * vb[:, j:j + 1] for j in range(3)]
    vd = _mid(derivative(log, slice(3, 6), window_s))[m]
    vd[:, 2] += G
    return np.stack(cols, axis=-1).reshape(-1, len(cols)), vd.reshape(-1)    # rows: (sample, world axis)


def fit_translation_rows(rows: Sequence[tuple[np.ndarray, np.ndarray] | None], *, delay_steps: int = 0,
                         drag: bool = True, rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM) -> TranslationModel:
    """:func:`fit_translation` from the logs' :func:`translation_rows` (made with the same settings)."""
    rows = [r for r in rows if r is not None]
    if not rows:
        raise DataError("fit_translation: no training row with every motor turning in flight")
    A, y = np.vstack([r[0] for r in rows]), np.concatenate([r[1] for r in rows])
    beta = robust_fit(A, y, lo=np.zeros(A.shape[1])).beta
    return TranslationModel(float(beta[0]), np.asarray(beta[1:4]) if drag else np.zeros(3),
                            int(delay_steps), float(rad_s_per_rpm))


# -- the vehicle ---------------------------------------------------------------------------------
#: translation and rotation together (:class:`droneid.simulation.openloop.IdentifiedVehicle`): the inputs
#: are the translation's and the rotation's side by side
VehicleModel = IdentifiedVehicle


def fit_vehicle(logs: Sequence[StateLog], layout: RotorLayout | str = "crazyflie_x", *,
                terms: tuple[str, ...] = ROTATION_TERMS, rotation_delay: int = 0,
                translation_delay: int = 0, window_s: float = 0.05, drag: bool = True,
                rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM) -> VehicleModel:
    """:func:`fit_translation` and :func:`fit_rotation` on the same training flights."""
    tr = fit_translation(logs, delay_steps=translation_delay, window_s=window_s, drag=drag,
                         rad_s_per_rpm=rad_s_per_rpm)
    rot = fit_rotation(logs, layout, terms=terms, delay_steps=rotation_delay, window_s=window_s,
                       rad_s_per_rpm=rad_s_per_rpm)
    return VehicleModel(tr, rot)


def identify_layout(logs: Sequence[StateLog], *, window_s: float = 0.05,
                    rad_s_per_rpm: float = 1.0, stride: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """The torque sign pattern from the data, for a frame whose layout is not declared.

    Per axis, ``ω̇_k`` is fitted on every ``s_i`` (plus rate damping and one trim per flight);
    the per-motor coefficients minus their mean (the part that sums to zero over the rotors, the
    rest being the collective thrust about an offset centre) give the pattern. Returns
    ``(signs (3, M), coefficients (3, M))``, rows roll, pitch, yaw. Every ``stride``-th in-flight
    row is fitted (the derivative is taken on every sample first): a sign needs far fewer rows
    than a coefficient (on the shared Crazyflie squares the pattern stands at ±15-20 rad/s² per
    unit against a ±1.7 yaw pattern, the same at stride 1 and 5), and it costs a fifth.
    """
    rows = []
    for log in logs:
        m = flying_mask(log)
        m[np.arange(m.size) % int(stride) != 0] = False
        s = _speeds(log, rad_s_per_rpm)[m] ** 2
        w = log.state[m, 10:13]
        rows.append((s, w, derivative(log, slice(10, 13), window_s)[m]))
    if not rows or not any(r[0].size for r in rows):
        raise DataError("identify_layout: no training row with every motor turning in flight")
    M = rows[0][0].shape[1]
    coefs = np.zeros((3, M))
    groups = np.concatenate([np.full(s.shape[0], j) for j, (s, _, _) in enumerate(rows)])
    for k in range(3):
        A = np.vstack([np.column_stack([s, -w[:, k]]) for s, w, _ in rows])
        # a trim per log: free intercepts profiled out (robust_fit_grouped: no one-hot columns)
        beta = robust_fit_grouped(A, np.concatenate([wd[:, k] for _, _, wd in rows]), groups).beta
        coefs[k] = beta[:M] - beta[:M].mean()
    return np.sign(coefs), coefs


#: the body axes in the order of the rotational targets
AXIS_NAMES = ("roll", "pitch", "yaw")
#: an axis whose ω̇ has no motor term (issue 37 item 5), in the report's and the export's words
NO_RESPONSE = "this axis does not respond to the motors (decay-only or held: no torque term)"


def unsteerable(rotation: "RotationModel | None") -> tuple[str, ...]:
    """The body axes that do not answer the motors: :meth:`RotationModel.unsteerable_axes`, all
    three without a rotational model (every rate held)."""
    return rotation.unsteerable_axes() if rotation is not None else AXIS_NAMES


def steering_line(rotation: "RotationModel | None") -> str:
    """Which body axes answer the motors and which do not, in one line (the export's header)."""
    stuck = unsteerable(rotation)
    answer = [a for a in AXIS_NAMES if a not in stuck]
    return (f"Body axes that answer the motors (a torque term): {', '.join(answer) or 'none'}"
            + (f"; {', '.join(stuck)}: {NO_RESPONSE}." if stuck else "."))


def unsteerable_sentence(axes: Sequence[str], inputs: str = "motor speeds") -> str:
    """What a user of the model must know when ``axes`` do not answer the motors ("" for none);
    ``inputs``: what the model is fed (motor speeds, or motor commands)."""
    if not axes:
        return ""
    return (f"NOT STEERABLE on {', '.join(axes)}: no torque term (decay-only or held), so differential "
            f"thrust does not turn the model there: replay logged {inputs} with it, do not design a "
            f"controller on it")
