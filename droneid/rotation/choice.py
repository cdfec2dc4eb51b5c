"""Choosing the rotational model (issue 28): the open-loop (simulation-error) fit of ω̇ and the
choice among candidate rotational models by blocked validation on TRAINING flights only, each
flight held out in turn and the vehicle run open loop on it (:mod:`droneid.simulation.openloop`). The models
themselves are in :mod:`droneid.rotation.model`. Rates in rad/s, attitude errors in rad.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from priors.torque import RotorLayout, get_layout

from droneid.errors import ConfigError, DataError
from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM, IdentifiedVehicle, StateLog, rollout, window_errors
from droneid.core.regression import robust_fit
from droneid.rotation.model import (RotationModel, segment_bounds, body_velocity, fit_rotation,
                       flying_mask, flying_segments, tilt, translation_rows)
from droneid.rotation.decay import DAMPING_GRID, damping_folds, damping_interval, fit_damping, regime_of
from droneid.rotation.folds import downdatable, rotation_folds, translation_folds
from droneid.rotation.ladder import AXES as _AXES, climb
from droneid.rotation.spinup import Spinup, fit_spinup, spinup_folds, spinup_interval

__all__ = ["fit_rotation_multistep", "select_rotation", "RotationChoice", "RUNGS", "VEHICLE_RUNGS",
           "fit_attitude", "AttitudeSpring", "per_axis_model", "STIFFNESS_GRID", "DEFAULT_CANDIDATES",
           "HeldRates", "validation_sums"]


# -- simulation-error fit of the rotation --------------------------------------------------------

def fit_rotation_multistep(logs: Sequence[StateLog], layout: RotorLayout | str = "crazyflie_x", *,
                           delay_steps: int | Sequence[int] = 0, horizon: int = 50, stride: int = 4,
                           damping_grid: Sequence[float] = DAMPING_GRID, spinup: bool = True,
                           centre_tau_s: float | None = None, lowpass_tau_s: float | None = None,
                           rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM, rotor_drag: bool = False,
                           balance_weight_s: float | None = None) -> RotationModel:
    """Fit ω̇ per axis by its open-loop error: the body rate predicted ``1..horizon`` steps
    ahead from every ``stride``-th start in flight, against the logged one.

    Per axis the model ``ω̇_k = a (P s)_k + e Σ s − c ω_k [+ r (P ṡpin)_yaw] + b_flight`` is linear
    in the inputs, so for a fixed damping ``c`` the ``h``-step prediction is linear in ``a, e, r,
    b``: ``ω_{t+h} − φ^h ω_t = Σ_{j<h} φ^{h−1−j} γ f_{t+j}`` with ``φ = e^{−c·dt}`` and
    ``γ = (1 − φ)/c`` (``dt`` at ``c = 0``), the input held over each step. Each ``c`` of the grid
    is fitted (Huber IRLS over all windows and horizons); the lowest mean absolute error wins. Gyroscopic
    coupling is left out (the axes decouple); trims are per training flight, their mean is kept.
    ``delay_steps`` may list candidates: the one with the lowest mean absolute error summed over the
    three axes (training flights only) is kept. ``centre_tau_s``: take the torque inputs about
    their causal moving average (:func:`centred`; uses motor speeds before the window).
    ``lowpass_tau_s``: low-pass the rotor speeds first (:func:`smoothed`, causal).
    ``rotor_drag``: add the rotor drag moment (roll, pitch), driven in the fit by the logged body
    velocity over the window. ``balance_weight_s``: torque inputs about their mean since the
    flight began (:func:`balanced`, prior the training mean).
    """
    layout = get_layout(layout) if isinstance(layout, str) else layout
    layout.check()
    delays = [int(delay_steps)] if np.ndim(delay_steps) == 0 else [int(d) for d in delay_steps]
    fits = []
    for d in delays:
        shell = RotationModel(layout, (), (np.zeros(0),) * 3, np.zeros(3), d, float(rad_s_per_rpm),
                              centre_tau_s=centre_tau_s, lowpass_tau_s=lowpass_tau_s)
        if balance_weight_s is not None:
            prior = np.concatenate([shell.conditioned(log.rpm, log.dt_s)[0][flying_mask(log)] for log in logs])
            shell = dataclasses.replace(shell, balance_weight_s=float(balance_weight_s),
                                        balance_prior=prior.mean(axis=0) if prior.size else None)
        fits.append((shell,) + _fit_multistep_at(logs, shell, int(horizon), stride, damping_grid,
                                                 spinup, rotor_drag))
    shell, loss, coef, trims, terms = min(fits, key=lambda f: f[1])
    return dataclasses.replace(shell, terms=terms, coef=coef, trim=trims.mean(axis=0), flight_trims=trims)


def _fit_multistep_at(logs, shell, H, stride, damping_grid, spinup, rotor_drag=False):
    """(summed loss, coef, per-flight trims, terms) of the multi-step fit with the input
    conditioning of ``shell`` (a :class:`RotationModel`)."""
    P = shell.layout.patterns()
    per_log = []
    for j, log in enumerate(logs):
        s_all, rate_all = shell.conditioned(log.rpm, log.dt_s)
        vb_all = body_velocity(log.state[:, 6:10], log.state[:, 3:6])
        for a, b in segment_bounds(log, H + 1):
            seg = StateLog(log.name, log.t_s[a:b], log.state[a:b], log.rpm[a:b], log.dt_s)
            s = s_all[a:b]
            vb = vb_all[a:b]
            feats = [s @ P.T, s.sum(axis=1), rate_all[a:b] @ P[2],
                     [vb[:, 1], -vb[:, 0]], [vb[:, 1] * s.sum(axis=1), -vb[:, 0] * s.sum(axis=1)]]
            starts = np.arange(0, len(seg) - H, stride)
            per_log.append((j, seg, feats, starts))
    if not per_log:
        raise DataError(f"fit_rotation_multistep: no flight segment longer than {H} steps")
    dt = logs[0].dt_s
    n_f = len(logs)
    terms = ("centre", "damping") + (("spinup",) if spinup else ()) + (("rotor_drag",) if rotor_drag else ())
    coef, trims, total = [], np.zeros((n_f, 3)), 0.0
    for k in range(3):
        best = None
        for c in damping_grid:
            phi = float(np.exp(-c * dt))
            gam = dt if c == 0 else (1.0 - phi) / c
            A, y = [], []
            for j, seg, (mix, S, spin, drag, _), starts in per_log:
                idx = starts[:, None] + np.arange(H)[None, :]
                f = [mix[:, k][idx], S[idx]] + ([spin[idx]] if spinup and k == 2 else [])
                f += [drag[k][idx]] if rotor_drag and k < 2 else []
                f.append(np.ones_like(idx, dtype=float))
                X = np.zeros((starts.size, H, len(f)))
                acc = np.zeros((starts.size, len(f)))
                for h in range(H):
                    acc = phi * acc + gam * np.stack([g[:, h] for g in f], axis=1)
                    X[:, h] = acc
                w0 = seg.state[starts, 10 + k]
                target = seg.state[idx + 1, 10 + k] - (phi ** np.arange(1, H + 1))[None, :] * w0[:, None]
                onehot = np.zeros((X.shape[0] * H, n_f))
                onehot[:, j] = X[:, :, -1].reshape(-1)
                A.append(np.hstack([X[:, :, :-1].reshape(-1, len(f) - 1), onehot]))
                y.append(target.reshape(-1))
            A, y = np.vstack(A), np.concatenate(y)
            lo = np.full(A.shape[1], -np.inf)
            lo[0] = 0.0
            fit = robust_fit(A, y, lo=lo)
            loss = float(np.mean(np.abs(y - A @ fit.beta)))   # the metric is an MAE
            if best is None or loss < best[0]:
                best = (loss, c, fit.beta)
        loss, c, beta = best
        total += loss
        nf = A.shape[1] - n_f
        b = beta[:nf]
        # columns of _rotation_named: pattern, centre, damping (−ω), [spinup on yaw], [rotor drag]
        ck = [b[0], b[1], c] + list(b[2:])
        coef.append(np.array(ck))
        trims[:, k] = beta[nf:]
    return total, tuple(coef), trims, terms


# -- choosing the rotational model by blocked validation ------------------------------------------
#: the torque models :func:`select_rotation` tries by default (keywords of :func:`fit_rotation`):
#: terms, rotor-speed delay (steps), low-pass time constant (s) and balance prior weight (s).
#: Narrowed by their validation on the shared Crazyflie squares (docs/use-the-model.md): from a
#: 36-candidate grid (also no rotor drag, no low-pass, no balance: worse everywhere), then from
#: delays 0-2 steps and terms with and without ``rotor_drag_thrust`` (pooled body-rate SimErr of
#: delays 0 / 1 / 2: 37.5 / 38.0 / 39.6 without it, 36.7 / 37.1 / 38.5 with it, rad/s)
DEFAULT_CANDIDATES = ({"terms": ("centre", "rotor_drag", "rotor_drag_thrust", "damping"), "delay_steps": 0,
                       "lowpass_tau_s": 0.05, "balance_weight_s": 1.0},)
#: the rungs of each axis's ladder, simplest first (``attitude``: roll and pitch only; ``spinup``:
#: yaw only, the decay plus the rotors' reaction to their spin-up, :mod:`droneid.rotation.spinup`)
RUNGS = ("held", "damping", "attitude", "spinup", "torque")
#: the rungs :func:`select_rotation` climbs by default: the airframe's own physics only. The
#: attitude spring is the onboard controller holding the vehicle level, not the vehicle: it
#: assumes the flight's attitude setpoint is level (true of the squares between corners, false of
#: any flight that holds a tilt) and, in a simulator that closes its own controller around the
#: model, it would count the controller twice. Opt in with ``rungs=RUNGS``.
VEHICLE_RUNGS = ("held", "damping", "spinup", "torque")
#: attitude stiffness values (1/s²) tried by :func:`fit_attitude`
STIFFNESS_GRID = (0.0, 2.5, 5.0, 10.0, 20.0, 40.0, 80.0, 160.0)
_CHUNK = 8192   # windows simulated at once


@dataclass(frozen=True)
class RotationChoice:
    """The rotational model chosen by :func:`select_rotation`.

    ``model``: the per-axis model refitted on every training flight (each axis at its rung of
    ``axis_choice``), or ``None`` when every axis holds its rate. ``table``: one row per model
    validated: the torque candidates (their settings), the ``{"method": "damping"}`` rung, the
    ``{"method": "attitude"}`` rung (roll and pitch; its yaw decays as the damping rung's) and,
    last, the ``{"method": "per-axis"}`` model actually chosen; each with its validation SimErr of body
    rates (rad/s) and attitude (rad), summed over ``h = 1..50`` (the nanodrone metric), pooled over
    the held-out flights, and per body axis ``rates_axis_simerr`` (Σ_h mean |Δω_k|: each
    rotational target's verdict); ``held``: the same for the rates held (ω̇ = 0, the benchmark's
    Physics row, each target's baseline); ``chosen``: index into ``table`` of the per-axis row
    (``None`` when every axis is held). ``axis_choice``: per axis (roll, pitch, yaw) one of
    :data:`RUNGS`; ``ladder``: per axis its steps (:func:`select_rotation`): each rung against the
    rung below, its wins per held-out flight and regime, its error ratio per regime, the cells,
    the rule's p, Holm threshold, effect (% lower pooled SimErr) and evidence line, and whether it
    was taken; with the test's ``alpha``, ``family_size`` and ``min_effect_pct``.
    """
    model: RotationModel | None
    table: tuple[dict, ...]
    held: dict
    chosen: int | None
    axis_choice: tuple[str, ...] = ("held", "held", "held")
    ladder: tuple[dict, ...] = ()

    @property
    def beats_held(self) -> bool:
        return self.model is not None

    def to_dict(self) -> dict:
        """JSON-able: ``{"model": RotationModel.to_dict() | None, "table", "held", "chosen",
        "axis_choice", "ladder"}``."""
        table = [{k: (list(v) if isinstance(v, tuple) else v) for k, v in row.items()} for row in self.table]
        return {"model": None if self.model is None else self.model.to_dict(), "table": table,
                "held": dict(self.held), "chosen": self.chosen, "axis_choice": list(self.axis_choice),
                "ladder": [dict(r) for r in self.ladder]}


class HeldRates:
    """ω̇ = 0 (the body rates held), as a rotational model for :class:`IdentifiedVehicle`."""
    input_width = 0

    def inputs(self, log: StateLog) -> np.ndarray:
        return np.zeros((len(log), 0))

    def ang_accel(self, state, u) -> np.ndarray:
        return np.zeros((state.shape[0], 3))


@dataclass(frozen=True)
class AttitudeSpring:
    """The closed loop holding the vehicle level, roll and pitch (:func:`fit_attitude`):
    ``ω̇_k = −c_k ω_k − κ_k (θ_k − θ0_k)``. ``damping_per_s`` ``c`` (2,) 1/s, ``stiffness_per_s2``
    ``κ`` (2,) 1/s², ``level_rad`` ``θ0`` (2,) rad (Z-Y-X roll and pitch)."""
    damping_per_s: np.ndarray
    stiffness_per_s2: np.ndarray
    level_rad: np.ndarray


def fit_attitude(logs: Sequence[StateLog], *, damping_grid: Sequence[float] = DAMPING_GRID,
                 stiffness_grid: Sequence[float] = STIFFNESS_GRID, horizon: int = 50, stride: int = 5,
                 regimes: int = 4) -> AttitudeSpring:
    """Roll and pitch as a spring-damper about the level attitude, ``ω̇_k = −c_k ω_k − κ_k (θ_k −
    θ0_k)``: the onboard attitude controller pulling the vehicle back to level through its rate
    loop (a model of the vehicle with its controller). ``θ0`` is the training flights' median
    roll and pitch in flight (the level as the log's frames see it). ``(c, κ)`` per axis is the
    pair of the grids with the lowest worst-regime open-loop error of the rate, as
    :func:`fit_damping` (the angle and rate predicted together by the linear spring-damper,
    ``θ̇ = ω`` for small angles, stepped by RK4, from every ``stride``-th start in flight)."""
    H = int(horizon)
    th_all = [tilt(log.state[a:b, 6:10]) for log in logs for a, b in segment_bounds(log, H + 1)]
    if not th_all:
        raise DataError(f"fit_attitude: no flight segment longer than {H} steps")
    level = np.median(np.concatenate(th_all), axis=0)
    dt = logs[0].dt_s
    pairs = [(float(c), float(kap)) for c in damping_grid for kap in stiffness_grid]
    A = np.zeros((len(pairs), 2, 2))
    A[:, 0, 1] = 1.0
    A[:, 1, 0] = [-kap for _, kap in pairs]
    A[:, 1, 1] = [-c for c, _ in pairs]
    Ad = A * dt                                   # one RK4 step of the linear system, as simulate
    step = np.eye(2) + Ad + Ad @ Ad / 2.0 + Ad @ Ad @ Ad / 6.0 + Ad @ Ad @ Ad @ Ad / 24.0
    gain = np.empty((len(pairs), H, 2))           # ω_{t+h} = gain[., h] · (θ_t, ω_t)
    cur = np.broadcast_to(np.eye(2), step.shape)
    for h in range(H):
        cur = step @ cur
        gain[:, h] = cur[:, 1]
    c_out, k_out = np.zeros(2), np.zeros(2)
    for k in range(2):
        w0, th0, wt = [], [], []
        for log in logs:
            for a, b in segment_bounds(log, H + 1):
                starts = np.arange(0, b - a - H, stride)
                w = log.state[a:b, 10 + k]
                w0.append(w[starts])
                th0.append(tilt(log.state[a + starts, 6:10])[:, k] - level[k])
                wt.append(w[starts[:, None] + np.arange(1, H + 1)[None, :]])
        w0, th0, wt = np.concatenate(w0), np.concatenate(th0), np.concatenate(wt)
        held = np.abs(wt - w0[:, None]).sum(axis=1)
        cls = regime_of(held, regimes)
        worst = np.zeros(len(pairs))
        for i in range(len(pairs)):
            err = np.abs(wt - (gain[i, None, :, 0] * th0[:, None] + gain[i, None, :, 1] * w0[:, None])).sum(axis=1)
            worst[i] = max(err[cls == q].mean() / max(held[cls == q].mean(), 1e-300) for q in np.unique(cls))
        c_out[k], k_out[k] = pairs[int(np.argmin(worst))]
    return AttitudeSpring(c_out, k_out, level)


def _damping_model(layout: RotorLayout, c, rad_s_per_rpm: float) -> RotationModel:
    """``ω̇_k = −c_k ω_k`` as a :class:`RotationModel` (its torque pattern at zero)."""
    return RotationModel(layout, ("damping",), tuple(np.array([0.0, float(ck)]) for ck in c), np.zeros(3),
                         rad_s_per_rpm=float(rad_s_per_rpm))


def per_axis_model(rungs: Sequence[str], damping, torque: RotationModel | None, layout: RotorLayout,
                   rad_s_per_rpm: float, attitude: AttitudeSpring | None = None,
                   spinup: Spinup | None = None) -> RotationModel | None:
    """One :class:`RotationModel` whose axis ``k`` is held (ω̇_k = 0), damped (``−damping[k] ω_k``),
    the attitude spring's (roll and pitch: ``attitude``), the spin-up rung's (yaw: ``spinup``) or
    the torque model's, as ``rungs[k]`` says; ``None`` when every axis is held. The torque model's
    conditioning (delay, low-pass, balance) is kept; its terms gain ``damping`` (and ``attitude``,
    ``spinup``) if needed. Without a torque axis the conditioning is the spin-up rung's (its
    alignment and motor lag); with one the spin-up gain reads the torque model's (one
    conditioning per model: that combination is what the choice's per-axis row validates)."""
    if all(r == "held" for r in rungs):
        return None
    for need, have in (("torque", torque), ("attitude", attitude), ("spinup", spinup)):
        if need in rungs and have is None:
            raise DataError(f"per_axis_model: an axis takes the {need} rung but no {need} model is given")
    if any(r == "attitude" for r in rungs[2:]):
        raise DataError("per_axis_model: the attitude rung is for roll and pitch only")
    if any(r == "spinup" for r in rungs[:2]):
        raise DataError("per_axis_model: the spin-up rung is for yaw only")
    extra = ("damping",) + (("attitude",) if "attitude" in rungs else ()) + (("spinup",) if "spinup" in rungs else ())
    if torque is None:
        base = RotationModel(layout, extra, (np.zeros(0),) * 3, np.zeros(3), rad_s_per_rpm=float(rad_s_per_rpm))
        if spinup is not None and "spinup" in rungs:
            base = dataclasses.replace(base, delay_steps=int(spinup.delay_steps), lowpass_tau_s=spinup.lowpass_tau_s)
    else:
        base = dataclasses.replace(torque, terms=tuple(torque.terms) + tuple(t for t in extra if t not in torque.terms))
    if attitude is not None and "attitude" in rungs:
        base = dataclasses.replace(base, level_rad=np.asarray(attitude.level_rad, float))
    coef, trim = [], np.zeros(3)
    for k, rung in enumerate(rungs):
        names = base.columns(k)
        if rung == "torque":
            have = dict(zip(torque.columns(k), torque.coef[k]))
        elif rung == "attitude":
            have = {"damping": attitude.damping_per_s[k], "attitude": attitude.stiffness_per_s2[k]}
        elif rung == "spinup":
            have = {"damping": spinup.damping_per_s, "spinup": spinup.gain}
        else:
            have = {"damping": damping[k]} if rung == "damping" else {}
        coef.append(np.array([float(have.get(nm, 0.0)) for nm in names]))
        if rung == "torque":
            trim[k] = torque.trim[k]
    flight_trims = base.flight_trims.copy()
    if flight_trims.size:
        flight_trims[:, [k for k, r in enumerate(rungs) if r != "torque"]] = 0.0
    return dataclasses.replace(base, coef=tuple(coef), trim=trim, flight_trims=flight_trims)


def select_rotation(logs: Sequence[StateLog], layout: RotorLayout | str = "crazyflie_x", *,
                    candidates: Sequence[dict] = DEFAULT_CANDIDATES, translation_delay_steps: int = 3,
                    stride: int = 20, window_s: float = 0.05,
                    rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM, regimes: int = 4,
                    alpha: float = 0.01, min_effect_pct: float = 1.0,
                    damping_grid: Sequence[float] = DAMPING_GRID,
                    rungs: Sequence[str] = VEHICLE_RUNGS) -> RotationChoice:
    """Choose the rotational model per body axis by blocked validation on TRAINING flights only.

    Each flight (logs of the same name form one block) is held out in turn. On the others are
    fitted a :class:`TranslationModel` (``translation_delay_steps``), the rate decay of
    :func:`fit_damping`, the attitude spring of :func:`fit_attitude` and every torque candidate
    (keyword arguments of :func:`fit_rotation`, or with ``"method": "multistep"`` of
    :func:`fit_rotation_multistep`); the vehicle is run open loop on the held-out flight's
    in-flight stretches from every ``stride``-th start. The torque candidate with the lowest
    pooled body-rate SimErr (attitude breaks ties) stands for the torque rung.

    Each axis then climbs the ladder ``rungs`` (a subsequence of :data:`RUNGS` starting at
    ``held``; default :data:`VEHICLE_RUNGS`): ``held`` (ω̇_k = 0) → ``damping`` (−c_k ω_k) →
    [``attitude``, opt-in: roll and pitch only: −c_k ω_k − κ_k (θ_k − θ0_k), the controller
    holding the vehicle level] → [``spinup``, yaw only: the decay plus the rotors' reaction to
    their spin-up, :mod:`droneid.rotation.spinup`, its alignment, motor lag and gain chosen per
    fold on the other flights] → ``torque``, one rung at a time, each rung tested against the rung
    directly below it. The validation windows of an axis are split into ``regimes`` classes by how
    far the held rate drifts in them (quantiles of the held body-rate error of the axis, so calm
    stretches, ordinary flight and hard manoeuvres each count on their own); every (held-out
    flight, regime) cell with at least 3 windows is one unit, its figure the axis's mean body-rate
    SimErr there. The pooled SimErr alone is ruled by the few windows where the rates change
    most (the squares' corners: the top quarter of the held error is ~4× its median), and a model
    that wins there and loses in calm flight does not transfer to flights that are mostly calm.

    The decision is :mod:`droneid.fitting.decide`'s one calibrated rule (:func:`droneid.fitting.decide.decide_units`):
    ``d = ln(SimErr without / SimErr with)`` per cell, the one-sided sign-flip test over the cells,
    Holm's step-down at ``alpha`` over every step of every axis (7 by default: roll and pitch
    decay and torque, yaw decay, spin-up and torque), and
    the pooled SimErr of the axis lower by at least ``min_effect_pct`` %. A rung is taken when its
    step is accepted and the axis took every rung below it. More training flights give more
    cells, so more power: 2 flights (8 cells, p ≥ 2^−8) cannot pass α/7 = 0.0014; 3 can.

    The chosen rungs are refitted on every training flight and combined by
    :func:`per_axis_model`; the per-axis model's own validation (its folds combined alike) is
    the last row of the table. ConfigError for ``regimes`` < 1 or ``alpha`` outside (0, 1).
    """
    names = list(dict.fromkeys(log.name for log in logs))
    if len(names) < 2:
        raise DataError("select_rotation needs at least two training flights to validate on")
    if not candidates:
        raise DataError("select_rotation: no candidate settings")
    if int(regimes) != regimes or regimes < 1:
        raise ConfigError(f"The 'regimes' parameter of select_rotation must be a positive integer. Got {regimes!r} instead.")
    if not 0.0 < alpha < 1.0:
        raise ConfigError(f"The 'alpha' parameter of select_rotation must be in (0, 1). Got {alpha!r} instead.")
    regimes = int(regimes)
    rungs = tuple(rungs)
    if not rungs or rungs[0] != "held" or any(r not in RUNGS for r in rungs) \
            or list(rungs) != sorted(set(rungs), key=RUNGS.index):
        raise ConfigError(f"The 'rungs' parameter of select_rotation must start at 'held' and follow the order of "
                          f"{', '.join(RUNGS)}. Got {rungs!r} instead.")
    spring_rung, spin_rung = "attitude" in rungs, "spinup" in rungs
    layout = get_layout(layout) if isinstance(layout, str) else layout
    tkw = {"delay_steps": translation_delay_steps, "rad_s_per_rpm": rad_s_per_rpm}
    trows = [translation_rows(log, window_s=window_s, **tkw) for log in logs]   # once per log
    # the leave-one-flight-out fits from sums over the flights computed once (droneid.rotation.folds)
    trs = translation_folds(trows, [log.name for log in logs], **tkw)
    decays = damping_folds(logs, grid=damping_grid, regimes=regimes)
    spins = spinup_folds(logs, layout, decays, rad_s_per_rpm=rad_s_per_rpm, regimes=regimes) if spin_rung else {}
    shared = [rotation_folds(logs, layout, cand, window_s=window_s, rad_s_per_rpm=rad_s_per_rpm)
              if downdatable(cand) else None for cand in candidates]
    folds = []   # per held-out flight: name, test segments, translation, damping c, torque fits, errors
    for name in names:
        train = [log for log in logs if log.name != name]
        test = [seg for log in logs if log.name == name for seg in flying_segments(log)]
        if not test or not _windows_in(test, stride):
            continue
        tr, c = trs[name], decays[name]
        torques = [sh[name] if sh is not None else _fit_candidate(train, layout, cand, window_s, rad_s_per_rpm)
                   for sh, cand in zip(shared, candidates)]
        errs = {"held": _window_errors(IdentifiedVehicle(tr, HeldRates()), test, stride),
                "damping": _window_errors(IdentifiedVehicle(tr, _damping_model(layout, c, rad_s_per_rpm)), test, stride)}
        spring = None
        if spring_rung:
            spring = fit_attitude(train, damping_grid=damping_grid, regimes=regimes)
            springs = per_axis_model(("attitude", "attitude", "damping"), c, None, layout, rad_s_per_rpm, spring)
            errs["attitude"] = _window_errors(IdentifiedVehicle(tr, springs), test, stride)
        if spin_rung:
            spun = per_axis_model(("damping", "damping", "spinup"), c, None, layout, rad_s_per_rpm, spinup=spins[name])
            errs["spinup"] = _window_errors(IdentifiedVehicle(tr, spun), test, stride)
        errs.update({i: _window_errors(IdentifiedVehicle(tr, m), test, stride) for i, m in enumerate(torques)})
        folds.append({"name": name, "test": test, "tr": tr, "c": c, "spring": spring, "spin": spins.get(name),
                      "torques": torques, "errs": errs})
    if not folds:
        raise DataError("select_rotation: no held-out flight has an in-flight stretch to validate on")
    held_row = _pooled(f["errs"]["held"] for f in folds)
    cand_rows = [{**dict(cand), **_pooled(f["errs"][i] for f in folds)} for i, cand in enumerate(candidates)]
    damp_row = {"method": "damping", "damping_per_s": [float(v) for v in np.median([f["c"] for f in folds], axis=0)],
                # per axis the lowest and highest decay of the leave-one-flight-out refits (1/s)
                "damping_per_s_range": [[float(v) for v in np.min([f["c"] for f in folds], axis=0)],
                                        [float(v) for v in np.max([f["c"] for f in folds], axis=0)]],
                # per axis the 95 % block-bootstrap interval of the decay fitted on every training flight
                "damping_per_s_interval": [[float(lo), float(hi)] for lo, hi in
                                           damping_interval(logs, grid=damping_grid, regimes=regimes)],
                "damping_grid": [float(v) for v in damping_grid],
                **_pooled(f["errs"]["damping"] for f in folds)}
    att_rows = ({"method": "attitude",
                 "damping_per_s": [float(v) for v in np.median([f["spring"].damping_per_s for f in folds], axis=0)],
                 "stiffness_per_s2": [float(v) for v in np.median([f["spring"].stiffness_per_s2 for f in folds], axis=0)],
                 **_pooled(f["errs"]["attitude"] for f in folds)},) if spring_rung else ()
    final_c = fit_damping(logs, grid=damping_grid, regimes=regimes)
    spin = fit_spinup(logs, layout, final_c[2], rad_s_per_rpm=rad_s_per_rpm, regimes=regimes) if spin_rung else None
    spin_rows = ({"method": "spinup", **spin.to_dict(),
                  # the settings of the leave-one-flight-out refits, and the gain's 95 % block-bootstrap interval
                  "folds": [f["spin"].to_dict() for f in folds],
                  "gain_interval": list(spinup_interval(logs, layout, spin, final_c[2], rad_s_per_rpm=rad_s_per_rpm,
                                                        regimes=regimes)),
                  **_pooled(f["errs"]["spinup"] for f in folds)},) if spin_rung else ()
    best = min(range(len(candidates)), key=lambda i: (cand_rows[i]["rates_simerr"], cand_rows[i]["attitude_simerr"]))
    for f in folds:
        f["errs"]["torque"] = f["errs"][best]
    rungs, steps, family = climb(folds, rungs, regimes, alpha, min_effect_pct)
    ladder = [{"axis": _AXES[k], "choice": rungs[k], "alpha": float(alpha), "family_size": family,
               "min_effect_pct": float(min_effect_pct), "regimes": int(regimes),
               "flights": [f["name"] for f in folds], "steps": steps[k]} for k in range(3)]
    table = tuple(cand_rows) + (damp_row, *att_rows, *spin_rows)
    if all(r == "held" for r in rungs):
        return RotationChoice(None, table, held_row, None, tuple(rungs), tuple(ladder))
    sums = []
    for f in folds:
        m = per_axis_model(rungs, f["c"], f["torques"][best], layout, rad_s_per_rpm, f["spring"], f["spin"])
        sums.append(_window_errors(IdentifiedVehicle(f["tr"], m), f["test"], stride))
    mixed_row = {"method": "per-axis", "axes": list(rungs), "torque_candidate": best, **_pooled(sums)}
    torque = _fit_candidate(logs, layout, candidates[best], window_s, rad_s_per_rpm) if "torque" in rungs else None
    spring = fit_attitude(logs, damping_grid=damping_grid, regimes=regimes) if "attitude" in rungs else None
    model = per_axis_model(rungs, final_c, torque, layout, rad_s_per_rpm, spring, spin)
    return RotationChoice(model, table + (mixed_row,), held_row, len(table), tuple(rungs), tuple(ladder))


def _windows_in(logs: Sequence[StateLog], stride: int, H: int = 50) -> int:
    return sum(len(range(0, len(log) - H, stride)) for log in logs if len(log) > H)


def _window_errors(model, logs: Sequence[StateLog], stride: int, H: int = 50) -> dict[str, np.ndarray]:
    """Per window of ``model`` open loop from every ``stride``-th start of each log (the nanodrone
    metric's windows, :func:`droneid.simulation.openloop.score_model`): ``rates`` and ``attitude`` SimErr
    (W,) and ``axis`` (W, 3), Σ_h |Δω_k|. The windows of all logs are simulated together, in
    chunks of ``_CHUNK``."""
    x0, uw, true = [], [], []
    for log in logs:
        if len(log) <= H:
            continue
        u = model.inputs(log)
        starts = np.arange(0, len(log) - H, stride)
        idx = starts[:, None] + np.arange(H)[None, :]
        x0.append(log.state[starts])
        uw.append(u[idx])
        true.append(log.state[idx + 1])
    if not x0:
        return {"rates": np.zeros(0), "attitude": np.zeros(0), "axis": np.zeros((0, 3))}
    x0, uw, true = np.concatenate(x0), np.concatenate(uw), np.concatenate(true)
    rates, att, axis = [], [], []
    for c in range(0, x0.shape[0], _CHUNK):
        pred, tr = rollout(model, x0[c:c + _CHUNK], uw[c:c + _CHUNK], logs[0].dt_s), true[c:c + _CHUNK]
        err = window_errors(pred, tr)
        rates.append(err["rates"].sum(axis=1))
        att.append(err["attitude"].sum(axis=1))
        axis.append(np.abs(pred[..., 10:13] - tr[..., 10:13]).sum(axis=1))
    return {"rates": np.concatenate(rates), "attitude": np.concatenate(att), "axis": np.concatenate(axis)}


def _pooled(errs) -> dict:
    """Validation figures pooled over the held-out flights' windows (see :class:`RotationChoice`)."""
    errs = list(errs)
    n = sum(e["rates"].size for e in errs)
    return {"rates_simerr": float(sum(e["rates"].sum() for e in errs) / n),
            "attitude_simerr": float(sum(e["attitude"].sum() for e in errs) / n),
            "rates_axis_simerr": [float(v) for v in sum(e["axis"].sum(axis=0) for e in errs) / n]}


def validation_sums(model, logs: Sequence[StateLog], stride: int, H: int = 50) -> tuple[int, np.ndarray]:
    """(windows, sums over windows of [rates SimErr, attitude SimErr, Σ_h |Δω_x|, |Δω_y|, |Δω_z|])
    of ``model`` open loop from every ``stride``-th start of each log."""
    e = _window_errors(model, logs, stride, H)
    return e["rates"].size, np.concatenate([[e["rates"].sum(), e["attitude"].sum()], e["axis"].sum(axis=0)])


def _fit_candidate(logs, layout, candidate: dict, window_s: float, rad_s_per_rpm: float) -> RotationModel:
    """One candidate of :func:`select_rotation`: ``method`` "equation" (default,
    :func:`fit_rotation`) or "multistep" (:func:`fit_rotation_multistep`), the rest its keywords."""
    c = dict(candidate)
    method = c.pop("method", "equation")
    if method == "multistep":
        return fit_rotation_multistep(logs, layout, rad_s_per_rpm=rad_s_per_rpm, **c)
    if method != "equation":
        raise DataError(f"select_rotation: unknown fitting method {method!r} (equation, multistep)")
    return fit_rotation(logs, layout, window_s=window_s, rad_s_per_rpm=rad_s_per_rpm, **c)
