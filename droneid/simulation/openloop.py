"""Open-loop simulation of the full vehicle state and the nanodrone benchmark's metric.

The metric is the one of idsia-robotics/nanodrone-sysid-benchmark (arXiv:2512.14450), as issue 28
states it: from the true state at every start time ``t`` of every test flight and the logged motor
speeds ``u_t … u_{t+H-1}``, predict the states at ``t+1 … t+H`` open loop (``H = 50`` steps at
100 Hz). ``MAE_h`` is the mean over all windows (pooled over flights) of

* the Euclidean norm of the 3-D error for position [m], velocity [m/s] and body rates [rad/s];
* for attitude, the geodesic angle ``2·atan2(‖q_v‖, |q_w|)`` of the error quaternion [rad].

It is reported at ``h = 1, 10, 50`` with ``SimErr = Σ_{h=1..H} MAE_h``. Input ``u_k`` is held
over the step from ``t+k`` to ``t+k+1`` (zero-order hold), as in the benchmark's dataset
(window ``i``: state ``x_i``, inputs ``u_i … u_{i+H-1}``, targets ``x_{i+1} … x_{i+H}``).

The state vector (``STATE_SIZE = 13``) is ``p (0:3, m, world ENU), v (3:6, m/s, world ENU),
q (6:10, Hamilton (qw, qx, qy, qz), FLU body to ENU world, unit norm), ω (10:13, rad/s, body
FLU)``. :func:`simulate` integrates it by classical RK4 for any model with two methods,

* ``accel(state, u) -> v̇`` (W, 3) in m/s², world ENU, and
* ``ang_accel(state, u) -> ω̇`` (W, 3) in rad/s², body FLU,

where ``state`` is (W, 13) and ``u`` is (W, K), the model's own inputs (by default the logged
motor speeds in rpm; a model may define ``inputs(log) -> (N, K)`` to choose and delay its inputs).
A model may instead define ``rollout(x0, u, dt_s)`` to predict without integration (:class:`Constant`).

Two reference models: :class:`NominalPhysics` (thrust from the motor speeds with a nominal thrust
coefficient, no drag, body rates held constant: the benchmark's ``Physics`` row) and
:class:`Constant` (the state held: the benchmark's ``Naive`` row). identify's v̇ models drive the
translation as :class:`IdentifiedTranslation` (body rates held); :class:`IdentifiedVehicle` steps
a translational and a rotational model (:class:`droneid.rotation.model.RotationModel`) together.
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import MappingProxyType

import numpy as np

from droneid.errors import ConfigError, DataError
from droneid.core.frames import euler_to_quat, qmul, quat_to_euler, quat_to_matrix
from droneid.logs.in_flight import in_flight_intervals, signal_gaps, subtract_intervals
from droneid.logs.screening import screen_signal
from droneid.simulation.motor_model import is_command, is_input_signal
from droneid.simulation.rk4 import rk4_step

__all__ = [
    "STATE_SIZE", "QUANTITIES", "HORIZONS", "MAX_HORIZON", "G", "StateLog", "state_log", "flight_state_logs",
    "quat_derivative", "quat_angle", "simulate", "rollout", "window_errors", "OpenLoopScore",
    "OpenLoopResult", "score_model", "open_loop", "NominalPhysics", "Constant",
    "CRAZYFLIE_RAD_S_PER_ERPM", "rad_s_per_rpm_text", "IdentifiedTranslation", "IdentifiedVehicle",
]

STATE_SIZE = 13
#: the metric's four quantities, in the order of the state vector
QUANTITIES = ("position", "velocity", "attitude", "rates")
#: the horizons (steps) the benchmark reports
HORIZONS = (1, 10, 50)
#: the benchmark's window length (steps); SimErr sums MAE_h over h = 1..MAX_HORIZON
MAX_HORIZON = 50
#: gravity (m/s²): fixed, never a free parameter
G = 9.81
#: Crazyflie 2.1 Brushless: motor speed in rad/s per logged electrical rpm (6 electrical per
#: mechanical revolution, as the benchmark converts ``m*_erpm``)
CRAZYFLIE_RAD_S_PER_ERPM = 2.0 * math.pi / (6.0 * 60.0)


def rad_s_per_rpm_text(factor: float) -> str:
    """The conversion of logged motor speeds to rad/s as a person checks it: ``2π/60 rad/s per
    rpm``, or ``2π/(60·6) rad/s per erpm (6 electrical rpm per mechanical revolution)``; never
    the bare number (2π/(60·6) is π/180, which reads as a degree mistake)."""
    for k in range(1, 21):
        if math.isclose(factor, 2.0 * math.pi / (60.0 * k), rel_tol=1e-12):
            return ("2π/60 rad/s per rpm" if k == 1 else
                    f"2π/(60·{k}) rad/s per erpm ({k} electrical rpm per mechanical revolution)")
    return f"{factor!r} rad/s per logged unit"

_P, _V, _Q, _W = slice(0, 3), slice(3, 6), slice(6, 10), slice(10, 13)
_QUAT, _EULER = ("qw", "qx", "qy", "qz"), ("roll", "pitch", "yaw")
_CHUNK = 8192  # windows simulated at once (memory: chunk x H x 13 float64)


# -- one flight on a uniform grid ---------------------------------------------------------------
@dataclass(frozen=True)
class StateLog:
    """One flight resampled on a uniform grid: the full state and the logged inputs.

    ``t_s`` (N,) seconds from the log start; ``state`` (N, 13) as described in the module
    docstring; ``rpm`` (N, M) motor speeds as logged (rpm, electrical where the log says erpm),
    in the vehicle's motor order ((N, 0) for a vehicle that logs commands only); ``dt_s`` the grid
    step; ``signals`` {name: (N,)} the other inputs asked for (motor commands ``motor1..`` or
    ``throttle`` in 0..1, ``battery_voltage`` in V; :mod:`droneid.simulation.motor_model`).
    """
    name: str
    t_s: np.ndarray
    state: np.ndarray
    rpm: np.ndarray
    dt_s: float
    signals: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        n = self.t_s.shape[0]
        if self.state.shape != (n, STATE_SIZE) or self.rpm.ndim != 2 or self.rpm.shape[0] != n:
            raise DataError(f"{self.name}: state log arrays disagree: t {self.t_s.shape}, "
                            f"state {self.state.shape}, rpm {self.rpm.shape}")
        bad = [k for k, v in self.signals.items() if np.shape(v) != (n,)]
        if bad:
            raise DataError(f"{self.name}: state log signals {', '.join(bad)} are not on the grid of {n} samples")
        # a plain dict (a mappingproxy cannot be pickled to the workers that score the logs)
        object.__setattr__(self, "signals", {k: np.asarray(v, float) for k, v in self.signals.items()})

    def column(self, name: str) -> np.ndarray:
        """The logged input ``name`` on the grid: ``rpm<i>`` or one of :attr:`signals`."""
        if name in self.signals:
            return self.signals[name]
        if re.fullmatch(r"rpm\d+", name) and int(name[3:]) <= self.rpm.shape[1]:
            return self.rpm[:, int(name[3:]) - 1]
        raise DataError(f"{self.name}: the open-loop simulation reads {name}, which the log lacks")

    def __len__(self) -> int:
        return int(self.t_s.shape[0])


def _continuous_quat(q: np.ndarray) -> np.ndarray:
    """Flip quaternion signs so that consecutive samples have a non-negative dot product."""
    q = np.array(q, dtype=float)
    flips = np.concatenate([[False], np.sum(q[1:] * q[:-1], axis=1) < 0])
    sign = np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)
    return q * sign[:, None]


def _signals(flight, motors: int | None = None, signals=()) -> tuple[list[str], list[str]]:
    """(state signals, motor-speed signals rpm1..M) a :class:`StateLog` reads; DataError naming
    what the flight lacks. With ``signals`` (other inputs: commands, battery voltage) the motor
    speeds may be absent (a command-driven vehicle)."""
    need = ("x", "y", "z", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "wx", "wy", "wz")
    if not any(q in flight for q in _QUAT) and all(a in flight for a in _EULER):
        need = tuple(n for n in need if n not in _QUAT) + _EULER   # the attitude as Euler angles
    missing = [n for n in need if n not in flight]
    if motors is None:
        motors = 0
        while f"rpm{motors + 1}" in flight:
            motors += 1
    rpm_names = [f"rpm{i}" for i in range(1, motors + 1)]
    missing += [n for n in (*rpm_names, *signals) if n not in flight]
    if missing or not (rpm_names or signals):
        raise DataError(f"{flight.name}: open-loop simulation needs "
                        f"{', '.join(missing) or 'per-motor speeds rpm1..rpmN'}, which the log lacks")
    return list(need), rpm_names


def flight_state_logs(flights, *, min_s: float = 0.6, signals=()) -> list[StateLog]:
    """The stretches of ``flights`` the open-loop metric may use, as :class:`StateLog` each named
    by its flight (so that a flight's stretches form one validation block; flights that share a
    name get their position in ``flights`` too): airborne and before
    any crash (:func:`droneid.logs.in_flight.in_flight_intervals`: a window on the ground with the
    motors off would score free fall against a vehicle at rest), with every gap and every
    screened implausible sample (:mod:`droneid.logs.screening`, the rule of the datasets and of the
    multi-step prediction) of the signals it reads cut out, so that no window interpolates across
    one. Stretches shorter than ``min_s`` seconds (no 50-step window at 100 Hz) are left out. Every
    stretch is on one grid step: the median step of ``x`` over all the flights. ``signals``: other
    inputs to carry (:attr:`StateLog.signals`; then the motor speeds are carried where the flights
    log them, and not needed), screened and cut like the rest."""
    flights = list(flights)
    names = [f.name for f in flights]
    # one grid step for every stretch (each stretch's own median step would differ on jittery
    # stamps, and windows of different steps cannot be pooled): the median over all the flights
    steps = np.concatenate([np.diff(f["x"].t) for f in flights if "x" in f and len(f["x"]) > 1] or [np.zeros(0)])
    dt_s = float(np.median(steps)) if steps.size else None
    out = []
    for i, f in enumerate(flights):
        # two flights with one name (the same file stem from two folders) are two blocks
        name = f.name if names.count(f.name) == 1 else f"{f.name} ({i + 1})"
        need, rpm_names = _signals(f, signals=signals)
        screened = [n for n in (*need, *rpm_names, *signals, "roll", "pitch", "yaw") if f.has(n)]
        holes = [h for n in screened for h in (*signal_gaps(f[n], 0.0), *screen_signal(f[n]).holes)]
        for a, b in subtract_intervals(in_flight_intervals(f)[0], sorted(holes)):
            if b - a > min_s:
                log = state_log(f.between(a, b), dt_s, signals=signals)
                out.append(log if name == log.name else replace(log, name=name))
    return out


def state_log(flight, dt_s: float | None = None, motors: int | None = None, signals=()) -> StateLog:
    """A :class:`StateLog` from a :class:`~droneid.logs.flight.Flight` with position, velocity,
    attitude quaternion, body rates and per-motor speeds (``rpm1..M``).

    Every signal is linearly interpolated onto one uniform grid over the span they all cover
    (step ``dt_s``, default the median step of ``x``); the quaternion is made sign-continuous,
    interpolated and renormalised (a log with Euler angles and no quaternion, as ArduCopter 3.3's
    ATT, gets the quaternion of its angles, made sign-continuous before it is interpolated).
    ``motors`` defaults to every consecutive ``rpmN`` present;
    ``signals``: other inputs to carry (:attr:`StateLog.signals`), interpolated alike.
    """
    need, rpm_names = _signals(flight, motors, signals)
    names = need + rpm_names + list(signals)
    t0 = max(flight[n].t[0] for n in names)
    t1 = min(flight[n].t[-1] for n in names)
    if dt_s is None:
        dt_s = float(np.median(np.diff(flight["x"].t)))
    if not (dt_s > 0 and math.isfinite(dt_s)):
        raise ConfigError(f"The 'dt_s' parameter of state_log must be a positive number. Got {dt_s!r} instead.")
    n = int(math.floor((t1 - t0) / dt_s + 1e-9)) + 1
    if n < 2:
        raise DataError(f"{flight.name}: the state and motor signals overlap for less than one step")
    t = t0 + dt_s * np.arange(n)

    def interp(name):
        s = flight[name]
        return np.interp(t, s.t, s.values)

    qs = [flight[c] for c in (_QUAT if _QUAT[0] in need else _EULER)]
    same = all(s.t.shape == qs[0].t.shape and np.array_equal(s.t, qs[0].t) for s in qs)
    if _QUAT[0] not in need:      # a log with Euler angles only (old ArduPilot ATT): their quaternion
        angles = [s.values if same else np.interp(qs[0].t, s.t, np.unwrap(s.values)) for s in qs]
        qc = _continuous_quat(euler_to_quat(*angles))
        q = np.column_stack([np.interp(t, qs[0].t, qc[:, k]) for k in range(4)])
    elif same:
        qc = _continuous_quat(np.column_stack([s.values for s in qs]))
        q = np.column_stack([np.interp(t, qs[0].t, qc[:, k]) for k in range(4)])
    else:
        q = np.column_stack([interp(c) for c in _QUAT])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    state = np.column_stack([interp(c) for c in ("x", "y", "z", "vx", "vy", "vz")]
                            + [q] + [interp(c) for c in ("wx", "wy", "wz")])
    rpm = np.column_stack([interp(c) for c in rpm_names]) if rpm_names else np.zeros((n, 0))
    return StateLog(flight.name, t, state, rpm, float(dt_s), {c: interp(c) for c in signals})


# -- quaternions ---------------------------------------------------------------------------------
def quat_derivative(q: np.ndarray, w_body: np.ndarray) -> np.ndarray:
    """``q̇ = ½ q ⊗ (0, ω)`` for Hamilton ``q`` (..., 4) and body rates ``ω`` (..., 3) in rad/s."""
    zero = np.zeros(w_body.shape[:-1] + (1,))
    return 0.5 * qmul(q, np.concatenate([zero, w_body], axis=-1))


def quat_angle(q_true: np.ndarray, q_pred: np.ndarray) -> np.ndarray:
    """Geodesic angle (rad, in [0, π]) between two attitudes: ``2·atan2(‖e_v‖, |e_w|)`` of the
    error quaternion ``e = q_true⁻¹ ⊗ q_pred`` (inputs (..., 4), need not be normalised)."""
    conj = q_true * np.array([1.0, -1.0, -1.0, -1.0])
    e = qmul(conj, q_pred)
    return 2.0 * np.arctan2(np.linalg.norm(e[..., 1:], axis=-1), np.abs(e[..., 0]))


# -- simulation ----------------------------------------------------------------------------------
def _normalise(q):
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _deriv(model, x, u):
    dx = np.empty_like(x)
    dx[:, _P] = x[:, _V]
    dx[:, _V] = model.accel(x, u)
    dx[:, _Q] = quat_derivative(x[:, _Q], x[:, _W])
    dx[:, _W] = model.ang_accel(x, u)
    return dx


def _stage(x, k, h):
    y = x + h * k
    y[:, _Q] = _normalise(y[:, _Q])
    return y


def simulate(model, x0, u, dt_s: float) -> np.ndarray:
    """Integrate the full state open loop by classical RK4.

    ``x0`` (W, 13) initial states; ``u`` (W, H, K) the model's inputs, ``u[:, k]`` held over the
    step from ``k`` to ``k + 1``; ``dt_s`` the step. Returns the states after each step,
    (W, H, 13). The quaternion is renormalised at every RK4 stage and after every step. A window
    whose model diverges holds inf or NaN from there on, silently (numpy's warnings are off).
    """
    x = np.array(x0, dtype=float)
    u = np.asarray(u, dtype=float)
    if x.ndim != 2 or x.shape[1] != STATE_SIZE or u.ndim != 3 or u.shape[0] != x.shape[0]:
        raise DataError(f"simulate: x0 must be (W, {STATE_SIZE}) and u (W, H, K); "
                        f"got {x.shape} and {u.shape}")
    out = np.empty((x.shape[0], u.shape[1], STATE_SIZE))
    # a model that diverges in a window gives inf/NaN there (scored as such), never a numpy
    # warning in the user's terminal (as droneid.simulation.rollout)
    with np.errstate(all="ignore"):
        x[:, _Q] = _normalise(x[:, _Q])
        for k in range(u.shape[1]):
            uk = u[:, k]
            x = rk4_step(lambda y, _at: _deriv(model, y, uk), x, dt_s, stage=_stage)
            x[:, _Q] = _normalise(x[:, _Q])
            out[:, k] = x
    return out


def rollout(model, x0, u, dt_s: float) -> np.ndarray:
    """The model's open-loop prediction (W, H, 13): its own ``rollout`` if it has one, else
    :func:`simulate`."""
    own = getattr(model, "rollout", None)
    if own is not None:
        return own(x0, u, dt_s)
    return simulate(model, x0, u, dt_s)


def _model_inputs(model, log: StateLog) -> np.ndarray:
    fn = getattr(model, "inputs", None)
    u = log.rpm if fn is None else np.asarray(fn(log), dtype=float)
    if u.ndim != 2 or u.shape[0] != len(log):
        raise DataError(f"{log.name}: a model's inputs must be (N, K) with N = {len(log)}, got {u.shape}")
    return u


# -- the metric ----------------------------------------------------------------------------------
def window_errors(pred: np.ndarray, true: np.ndarray) -> dict[str, np.ndarray]:
    """Per-window, per-step errors of predicted states against true ones, both (W, H, 13):
    {quantity: (W, H)} with the Euclidean norm of the 3-D error (position m, velocity m/s,
    rates rad/s) and the geodesic attitude angle (rad)."""
    if pred.shape != true.shape or pred.shape[-1] != STATE_SIZE:
        raise DataError(f"window_errors: predicted {pred.shape} and true {true.shape} states differ")
    return {"position": np.linalg.norm(pred[..., _P] - true[..., _P], axis=-1),
            "velocity": np.linalg.norm(pred[..., _V] - true[..., _V], axis=-1),
            "attitude": quat_angle(true[..., _Q], pred[..., _Q]),
            "rates": np.linalg.norm(pred[..., _W] - true[..., _W], axis=-1)}


@dataclass(frozen=True)
class OpenLoopScore:
    """One model's open-loop errors: ``mae[quantity][h-1]`` is MAE_h (h = 1..max_horizon),
    pooled over ``windows`` windows of the scored flights."""
    model: str
    mae: Mapping[str, np.ndarray]
    windows: int
    horizons: tuple[int, ...] = HORIZONS

    def __post_init__(self):
        object.__setattr__(self, "mae", MappingProxyType({k: np.asarray(v, float) for k, v in self.mae.items()}))

    @property
    def max_horizon(self) -> int:
        return int(len(next(iter(self.mae.values()))))

    def at(self, h: int) -> dict[str, float]:
        """{quantity: MAE_h} at horizon ``h`` (steps, 1-based)."""
        if not 1 <= h <= self.max_horizon:
            raise ConfigError(f"horizon {h} is outside 1..{self.max_horizon}")
        return {q: float(self.mae[q][h - 1]) for q in QUANTITIES}

    @property
    def simerr(self) -> dict[str, float]:
        """{quantity: Σ_{h=1..max_horizon} MAE_h}."""
        return {q: float(np.sum(self.mae[q])) for q in QUANTITIES}

    def to_dict(self) -> dict:
        """``{"1": {"position", "velocity", "attitude", "rates"}, "10": …, "50": …, "simerr": {…}}``."""
        out = {str(h): self.at(h) for h in self.horizons if h <= self.max_horizon}
        out["simerr"] = self.simerr
        return out


@dataclass(frozen=True)
class OpenLoopResult:
    """Open-loop scores of several models on the same flights and windows."""
    scores: tuple[OpenLoopScore, ...]
    flights: tuple[str, ...]
    dt_s: float
    max_horizon: int = MAX_HORIZON

    def __getitem__(self, model: str) -> OpenLoopScore:
        for s in self.scores:
            if s.model == model:
                return s
        raise KeyError(model)

    def to_dict(self) -> dict:
        """``{model name: OpenLoopScore.to_dict()}``, in the order the models were given."""
        return {s.model: s.to_dict() for s in self.scores}


def _windows(log: StateLog, u: np.ndarray, starts: np.ndarray, H: int):
    idx = starts[:, None] + np.arange(H)[None, :]
    return log.state[starts], u[idx], log.state[idx + 1]


def score_model(name: str, model, logs: Sequence[StateLog], *, max_horizon: int = MAX_HORIZON,
                horizons: Sequence[int] = HORIZONS, stride: int = 1) -> OpenLoopScore:
    """Score one model over every start time (every ``stride``-th) of every log: windows
    ``i = 0 … N-H-1`` of each log, errors pooled over all windows."""
    H = int(max_horizon)
    if H < 1 or stride < 1:
        raise ConfigError(f"max_horizon and stride must be positive; got {max_horizon!r}, {stride!r}")
    sums = {q: np.zeros(H) for q in QUANTITIES}
    count = 0
    for log in logs:
        if len(log) <= H:
            continue
        u = _model_inputs(model, log)
        starts_all = np.arange(0, len(log) - H, stride)
        for c in range(0, starts_all.size, _CHUNK):
            starts = starts_all[c:c + _CHUNK]
            x0, uw, xt = _windows(log, u, starts, H)
            err = window_errors(rollout(model, x0, uw, log.dt_s), xt)
            for q in QUANTITIES:
                sums[q] += err[q].sum(axis=0)
            count += starts.size
    if count == 0:
        raise DataError(f"no flight is longer than the horizon ({H} steps)")
    return OpenLoopScore(name, {q: sums[q] / count for q in QUANTITIES}, count, tuple(horizons))


def open_loop(models: Mapping[str, object], logs: Sequence[StateLog], *,
              max_horizon: int = MAX_HORIZON, horizons: Sequence[int] = HORIZONS,
              stride: int = 1) -> OpenLoopResult:
    """Score every model (name -> model) on the same windows of the same logs."""
    if not logs:
        raise DataError("open_loop needs at least one flight")
    dts = {round(log.dt_s, 9) for log in logs}
    if len(dts) != 1:
        raise DataError(f"open_loop: the flights have different grid steps {sorted(dts)}; resample them alike")
    scores = tuple(score_model(n, m, logs, max_horizon=max_horizon, horizons=horizons, stride=stride)
                   for n, m in models.items())
    return OpenLoopResult(scores, tuple(log.name for log in logs), logs[0].dt_s, int(max_horizon))


# -- reference models ----------------------------------------------------------------------------
@dataclass(frozen=True)
class NominalPhysics:
    """Nominal rigid body driven by the motor speeds (the benchmark's ``Physics`` row).

    ``v̇ = R(q) e_z · k_T Σ (s·u_i)² / m − g e_z`` (world ENU; no drag) and ``ω̇ = 0`` (the body
    rates are held at their initial value). ``u_i`` are the logged motor speeds, ``s`` converts
    them to rad/s. The defaults are the benchmark's Crazyflie 2.1 Brushless values: thrust
    coefficient ``k_T = 3.72e-8 N/(rad/s)²``, mass 0.045 kg, 6 electrical rpm per mechanical.
    """
    thrust_coeff_N_s2: float = 3.72e-8
    mass_kg: float = 0.045
    rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM
    g: float = G

    @classmethod
    def hover_matched(cls, logs: Sequence[StateLog], *, rad_s_per_rpm: float = 1.0,
                      g: float = G) -> "NominalPhysics":
        """A nominal model for a vehicle of unknown coefficients: ``k_T/m`` such that the median
        ``Σ u²`` of the given (training) flights, while the motors turn, gives ``g``."""
        s = np.concatenate([np.sum((rad_s_per_rpm * log.rpm) ** 2, axis=1) for log in logs])
        s = s[s > 0]
        if s.size == 0:
            raise DataError("hover_matched: the motors never turn in the given flights")
        return cls(thrust_coeff_N_s2=g / float(np.median(s)), mass_kg=1.0, rad_s_per_rpm=rad_s_per_rpm, g=g)

    def specific_thrust(self, u) -> np.ndarray:
        """Thrust per mass along body z (m/s²) from motor speeds ``u`` (W, M) as logged."""
        return self.thrust_coeff_N_s2 * np.sum((self.rad_s_per_rpm * u) ** 2, axis=-1) / self.mass_kg

    def accel(self, state, u) -> np.ndarray:
        a = quat_to_matrix(state[:, _Q])[:, :, 2] * self.specific_thrust(u)[:, None]
        a[:, 2] -= self.g
        return a

    def ang_accel(self, state, u) -> np.ndarray:
        return np.zeros((state.shape[0], 3))


@dataclass(frozen=True)
class Constant:
    """The state held at its initial value over the whole horizon (the benchmark's ``Naive``)."""

    def rollout(self, x0, u, dt_s: float) -> np.ndarray:
        x0 = np.asarray(x0, float)
        return np.repeat(x0[:, None, :], np.asarray(u).shape[1], axis=1)


@dataclass(frozen=True)
class IdentifiedTranslation:
    """identify's final v̇ models driven open loop: ``models`` {"vx_dot"|"vy_dot"|"vz_dot":
    :class:`~droneid.fitting.closed_form.IdentifiedModel`} give v̇ (world ENU) from the simulated state
    (velocity, and roll, pitch, yaw from the simulated quaternion) and the logged inputs: motor
    speeds ``rpm<i>``, or on a command-driven vehicle the commands ``motor<i>`` / ``throttle`` and
    ``battery_voltage``, each read at ``t − delay`` as identified (shifted by whole grid steps; a
    negative delay reads later samples). ``motor``: the identified motor model of a command-driven
    vehicle (:class:`droneid.simulation.motor_model.MotorModel`): with a motor lag the commands and
    the voltage are read at t and the models fed the effective commands the lagged rotors deliver
    (its docstring says why not also at the offset). Alone it holds the body rates (ω̇ = 0), as
    the benchmark's Physics row; with a rotational model it is the translation of
    :class:`IdentifiedVehicle`. A model reading another signal cannot be driven open loop."""
    models: Mapping[str, object]
    motor: object | None = None

    def __post_init__(self):
        missing = [t for t in ("vx_dot", "vy_dot", "vz_dot") if t not in self.models]
        if missing:
            raise DataError(f"open-loop simulation needs models of vx_dot, vy_dot and vz_dot; "
                            f"missing: {', '.join(missing)}")
        known = {"vx", "vy", "vz", "roll", "pitch", "yaw"}
        for t, m in self.models.items():
            other = [s for s in m.signals if s not in known and not is_input_signal(s)]
            if other:
                raise DataError(f"the {t} model reads {', '.join(other)}: open-loop simulation drives a model "
                                f"by the state and the logged motor speeds, commands and battery voltage only")
        if any(is_command(n) for n in self.input_names()) and self.motor is None:
            raise DataError("the v̇ models read motor commands: open-loop simulation needs the result's "
                            "motor model (its thrust curve) to drive them")

    def input_names(self) -> list[str]:
        """The logged inputs the models read: motor speeds, then commands, then the voltage."""
        names = {s for m in self.models.values() for s in m.signals if is_input_signal(s)}

        def key(n):
            digits = re.sub(r"\D", "", n)
            return ("rpm" not in n, n == "battery_voltage", re.sub(r"\d", "", n), int(digits or 0))
        return sorted(names, key=key)

    def signals(self) -> list[str]:
        """The inputs a :class:`StateLog` must carry beside the motor speeds (commands, voltage)."""
        return [n for n in self.input_names() if not n.startswith("rpm")]

    def delay_steps(self, target: str, name: str, dt_s: float) -> int:
        """Whole grid steps of ``dt_s`` the ``target`` model reads input ``name`` back: its delay,
        or 0 for a command or the voltage through a motor lag."""
        if self.motor is not None and self.motor.lagged and not name.startswith("rpm"):
            return 0
        return int(round(float(self.models[target].delays_s.get(name, 0.0)) / dt_s))

    def inputs(self, log: StateLog) -> np.ndarray:
        """(N, K): each model's inputs at ``t − delay`` (model by model, input by input), the
        commands through the motor model's lag where it has one."""
        names = self.input_names()
        cmds = [n for n in names if is_command(n)]
        cols = []
        for t in ("vx_dot", "vy_dot", "vz_dot"):
            read = {}
            for name in names:
                k = self.delay_steps(t, name, log.dt_s)
                idx = np.clip(np.arange(len(log)) - k, 0, len(log) - 1)
                read[name] = log.column(name)[idx]
            if cmds and self.motor.lagged:
                u = np.column_stack([read[n] for n in cmds])
                eff = self.motor.effective(u, read.get("battery_voltage"), log.dt_s)
                read.update({n: eff[:, i] for i, n in enumerate(cmds)})
            cols += [read[n] for n in names]
        return np.column_stack(cols) if cols else np.zeros((len(log), 0))

    def accel(self, state, u) -> np.ndarray:
        roll, pitch, yaw = quat_to_euler(state[:, _Q])
        base = {"vx": state[:, 3], "vy": state[:, 4], "vz": state[:, 5], "roll": roll, "pitch": pitch, "yaw": yaw}
        names = self.input_names()
        out = np.empty((state.shape[0], 3))
        for a, t in enumerate(("vx_dot", "vy_dot", "vz_dot")):
            cols = dict(base)
            cols.update({n: u[:, a * len(names) + i] for i, n in enumerate(names)})
            out[:, a] = self.models[t].evaluate(cols)
        return out

    def ang_accel(self, state, u) -> np.ndarray:
        return np.zeros((state.shape[0], 3))


@dataclass(frozen=True)
class IdentifiedVehicle:
    """The whole vehicle open loop: a translational model's v̇ and a rotational model's ω̇,
    stepped together by :func:`simulate` (RK4, unit quaternion) from the motor speeds alone.

    ``translation`` has ``inputs(log) -> (N, K_t)`` and ``accel(state, u) -> v̇`` (e.g.
    :class:`IdentifiedTranslation`, :class:`droneid.rotation.model.TranslationModel`); ``rotation`` has
    ``inputs(log) -> (N, K_r)``, ``input_width == K_r`` and ``ang_accel(state, u) -> ω̇`` (e.g.
    :class:`droneid.rotation.model.RotationModel`). Their inputs sit side by side, translation first.
    """
    translation: object
    rotation: object

    def inputs(self, log: StateLog) -> np.ndarray:
        return np.hstack([_model_inputs(self.translation, log), _model_inputs(self.rotation, log)])

    def accel(self, state, u) -> np.ndarray:
        return self.translation.accel(state, u[:, :u.shape[1] - self.rotation.input_width])

    def ang_accel(self, state, u) -> np.ndarray:
        return self.rotation.ang_accel(state, u[:, u.shape[1] - self.rotation.input_width:])
