"""Choosing the rotational model (issue 28): the open-loop (simulation-error) fit of ω̇ and the
choice among candidate rotational models by blocked validation on TRAINING flights only, each
flight held out in turn and the vehicle run open loop on it (:mod:`droneid.openloop`). The models
themselves are in :mod:`droneid.rotation`. Rates in rad/s, attitude errors in rad.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from priors.torque import RotorLayout, get_layout

from .errors import DataError
from .openloop import CRAZYFLIE_RAD_S_PER_ERPM, IdentifiedVehicle, StateLog, rollout, window_errors
from .regression import robust_fit
from .rotation import (RotationModel, _segment_bounds, body_velocity, fit_rotation, fit_translation,
                       flying_mask, flying_segments)

__all__ = ["fit_rotation_multistep", "select_rotation", "RotationChoice", "DAMPING_GRID",
           "DEFAULT_CANDIDATES"]


# -- simulation-error fit of the rotation --------------------------------------------------------
#: rate damping values (1/s) tried by :func:`fit_rotation_multistep`
DAMPING_GRID = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)


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
        for a, b in _segment_bounds(log, H + 1):
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
#: the settings :func:`select_rotation` tries by default: terms, rotor-speed delay (steps), low-pass
#: time constant (s) and balance prior weight (s). Narrowed from a 36-candidate grid (also no
#: rotor drag, no low-pass, no balance) by its validation on the shared Crazyflie squares, where
#: every candidate without the balance or the low-pass came out worse (docs/use-the-model.md)
DEFAULT_CANDIDATES = tuple(
    {"terms": terms, "delay_steps": d, "lowpass_tau_s": 0.05, "balance_weight_s": 1.0}
    for terms in (("centre", "rotor_drag", "damping"), ("centre", "rotor_drag", "rotor_drag_thrust", "damping"))
    for d in (0, 1, 2))


@dataclass(frozen=True)
class RotationChoice:
    """The rotational model chosen by :func:`select_rotation`.

    ``model``: the chosen settings refitted on every training flight, or ``None`` when no
    candidate beat holding the body rates on validation (then hold them). ``table``: per
    candidate its settings and validation SimErr of body rates (rad/s) and attitude (rad), summed
    over ``h = 1..50`` (the nanodrone metric), pooled over the held-out flights, and per body axis
    ``rates_axis_simerr`` (Σ_h mean |Δω_k|: the verdict of each rotational target); ``held``: the
    same for the rates held (ω̇ = 0, the benchmark's Physics row, each target's baseline);
    ``chosen``: index into ``table``.
    """
    model: RotationModel | None
    table: tuple[dict, ...]
    held: dict
    chosen: int | None

    @property
    def beats_held(self) -> bool:
        return self.model is not None

    def to_dict(self) -> dict:
        """JSON-able: ``{"model": RotationModel.to_dict() | None, "table", "held", "chosen"}``."""
        table = [{k: (list(v) if isinstance(v, tuple) else v) for k, v in row.items()} for row in self.table]
        return {"model": None if self.model is None else self.model.to_dict(), "table": table,
                "held": dict(self.held), "chosen": self.chosen}


class _HeldRates:
    """ω̇ = 0 (the body rates held), as a rotational model for :class:`IdentifiedVehicle`."""
    input_width = 0

    def inputs(self, log: StateLog) -> np.ndarray:
        return np.zeros((len(log), 0))

    def ang_accel(self, state, u) -> np.ndarray:
        return np.zeros((state.shape[0], 3))


def select_rotation(logs: Sequence[StateLog], layout: RotorLayout | str = "crazyflie_x", *,
                    candidates: Sequence[dict] = DEFAULT_CANDIDATES, translation_delay_steps: int = 3,
                    stride: int = 20, window_s: float = 0.05,
                    rad_s_per_rpm: float = CRAZYFLIE_RAD_S_PER_ERPM) -> RotationChoice:
    """Choose the rotational model by blocked validation on TRAINING flights only.

    Each flight (logs of the same name form one block) is held out in turn; every candidate
    (keyword arguments of :func:`fit_rotation`, or with ``"method": "multistep"`` of
    :func:`fit_rotation_multistep`) is fitted on the others, with a
    :class:`TranslationModel` fitted alike (``translation_delay_steps``), and the vehicle is run
    open loop on the held-out flight's in-flight stretches from every ``stride``-th start. The
    lowest pooled body-rate SimErr wins (attitude SimErr breaks ties), and only if it is below
    holding the rates; the winner is refitted on every flight.
    """
    names = list(dict.fromkeys(log.name for log in logs))
    if len(names) < 2:
        raise DataError("select_rotation needs at least two training flights to validate on")
    if not candidates:
        raise DataError("select_rotation: no candidate settings")
    sums = [np.zeros(5) for _ in candidates]
    held = np.zeros(5)
    windows = 0
    for name in names:
        train = [log for log in logs if log.name != name]
        test = [seg for log in logs if log.name == name for seg in flying_segments(log)]
        if not test:
            continue
        tr = fit_translation(train, delay_steps=translation_delay_steps, window_s=window_s,
                             rad_s_per_rpm=rad_s_per_rpm)
        n, err = _validation_sums(IdentifiedVehicle(tr, _HeldRates()), test, stride)
        windows += n
        held += err
        for i, c in enumerate(candidates):
            sums[i] += _validation_sums(IdentifiedVehicle(tr, _fit_candidate(train, layout, c, window_s,
                                                                              rad_s_per_rpm)), test, stride)[1]
    if windows == 0:
        raise DataError("select_rotation: no held-out flight has an in-flight stretch to validate on")

    def row(e):
        e = e / windows
        return {"rates_simerr": float(e[0]), "attitude_simerr": float(e[1]),
                "rates_axis_simerr": [float(v) for v in e[2:]]}

    table = tuple({**dict(c), **row(s)} for c, s in zip(candidates, sums))
    held_row = row(held)
    best = min(range(len(table)), key=lambda i: (table[i]["rates_simerr"], table[i]["attitude_simerr"]))
    if table[best]["rates_simerr"] >= held_row["rates_simerr"]:
        return RotationChoice(None, table, held_row, None)
    return RotationChoice(_fit_candidate(logs, layout, candidates[best], window_s, rad_s_per_rpm),
                          table, held_row, best)


def _validation_sums(model, logs: Sequence[StateLog], stride: int, H: int = 50) -> tuple[int, np.ndarray]:
    """(windows, sums over windows of [rates SimErr, attitude SimErr, Σ_h |Δω_x|, |Δω_y|, |Δω_z|])
    of ``model`` open loop from every ``stride``-th start of each log (the nanodrone metric's
    windows, :func:`droneid.openloop.score_model`)."""
    n, out = 0, np.zeros(5)
    for log in logs:
        if len(log) <= H:
            continue
        u = model.inputs(log)
        starts = np.arange(0, len(log) - H, stride)
        idx = starts[:, None] + np.arange(H)[None, :]
        pred, true = rollout(model, log.state[starts], u[idx], log.dt_s), log.state[idx + 1]
        err = window_errors(pred, true)
        out[0] += err["rates"].sum()
        out[1] += err["attitude"].sum()
        out[2:] += np.abs(pred[..., 10:13] - true[..., 10:13]).sum(axis=(0, 1))
        n += starts.size
    return n, out


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
