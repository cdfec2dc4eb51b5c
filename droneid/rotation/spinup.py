"""The yaw spin-up rung of the rotational ladder (issue 37.4): ``ω̇z = −c ω_z + r (P ṡpin)_z``,
the rate decay of :mod:`droneid.rotation.decay` plus the rotors' reaction to their own
acceleration. A rotor turning clockwise seen from above (spin +1) carries angular momentum along
−z; spinning it up pushes the body the other way, so the body's yaw acceleration is
``J_r/J_z Σ_i spin_i ω̇_i``: the yaw pattern of :mod:`priors.torque` applied to the rotor speed
rates, a motor term with a positive gain ``r`` (``r = 1000 J_r/J_z`` with the speed rates in
(1000 rad/s)/s, :data:`droneid.rotation.model.SPEED_UNIT`).

Three settings are chosen on TRAINING flights only, jointly, from grids, by the criterion of
:func:`droneid.rotation.decay.fit_damping`: the lowest worst-regime ratio of the open-loop yaw
SimErr (Σ_{h=1..50} |Δω_z|, rad/s) to the decay's (the smallest gain wins a tie):

* the time alignment of the motor stream, ``delay_steps`` (:data:`SPINUP_DELAYS`: 0-40 ms at
  100 Hz, the range of the thrust offset's own intervals on the shared Crazyflie squares; a
  reaction torque is instantaneous, so a longer delay would fit the yaw controller, not the rotor);
* the motor lag, a first-order low-pass of the rotor speeds (:data:`SPINUP_LOWPASS_S`, seconds;
  :func:`droneid.rotation.model.smoothed`), which also smooths the speed rates' differences;
* the gain ``r`` (:data:`SPINUP_GAINS`, 0 included: no reaction).

The decay ``c`` is the decay rung's (fitted first, on the same flights). The prediction is the
exact solution of the linear ODE with the input held over each step (the rollout steps it by
RK4: the same to ~1e-4 at 100 Hz). Rates in rad/s, times in s.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from priors.torque import RotorLayout

from droneid.errors import DataError
from droneid.simulation.openloop import StateLog
from droneid.core.regression import N_BOOT
from droneid.rotation.model import RotationModel, segment_bounds
from droneid.rotation.decay import regime_of
from droneid.dataset.validation import time_blocks

__all__ = ["SPINUP_DELAYS", "SPINUP_LOWPASS_S", "SPINUP_GAINS", "Spinup", "fit_spinup", "spinup_folds",
           "spinup_interval"]

#: motor-stream alignments tried (steps of the state grid; 0-40 ms at 100 Hz)
SPINUP_DELAYS = (0, 1, 2, 3, 4)
#: motor lags tried: time constants (s) of the causal first-order filter of the rotor speeds
SPINUP_LOWPASS_S = (None, 0.03, 0.06)
#: spin-up gains tried, rad/s² per (1000 rad/s)/s of the yaw pattern of the rotor speed rates
SPINUP_GAINS = (0.0, 0.01, 0.02, 0.05, 0.1, 0.2)


@dataclass(frozen=True)
class Spinup:
    """The yaw spin-up rung's settings: ``delay_steps`` of the motor stream, ``lowpass_tau_s`` of
    the motor lag (None: none), ``gain`` r (see the module docstring) and the yaw decay
    ``damping_per_s`` c it was fitted with."""
    delay_steps: int
    lowpass_tau_s: float | None
    gain: float
    damping_per_s: float

    def to_dict(self) -> dict:
        return {"delay_steps": int(self.delay_steps), "lowpass_tau_s": self.lowpass_tau_s,
                "gain": float(self.gain), "damping_per_s": float(self.damping_per_s)}


def _settings(decays, delays, lowpass, gains) -> list[tuple[float, int, float | None, float]]:
    return [(float(c), int(d), lp, float(g)) for c in decays for d in delays for lp in lowpass for g in gains]


def _spinup_errors(logs: Sequence[StateLog], layout: RotorLayout, c_ref: float, rad_s_per_rpm: float,
                   decays, delays, lowpass, gains, horizon: int, stride: int):
    """(err (S + 1, W), t (W,), flight (W,), settings): each window's open-loop yaw SimErr with
    the decay ``c_ref`` alone (first) and with each setting (decay, delay, low-pass, gain) of
    :func:`_settings`, its start time (s) and its flight's index (logs of one name are one flight)."""
    from scipy.signal import lfilter       # scipy.signal's import is heavy: only where it filters
    H = int(horizon)
    names = list(dict.fromkeys(log.name for log in logs))
    pattern = layout.patterns()[2]
    settings = _settings(decays, delays, lowpass, gains)
    errs, ts, fl = [], [], []
    for log in logs:
        bounds = [(a, b) for a, b in segment_bounds(log, H + 1) if b - a > H]
        if not bounds:
            continue
        drive = {}
        for d in delays:
            for lp in lowpass:
                shell = RotationModel(layout, (), (np.zeros(0),) * 3, np.zeros(3), int(d), float(rad_s_per_rpm),
                                      lowpass_tau_s=lp)
                drive[(int(d), lp)] = shell.conditioned(log.rpm, log.dt_s)[1] @ pattern
        for a, b in bounds:
            starts = a + np.arange(0, b - a - H, stride)
            idx = starts[:, None] + np.arange(H)[None, :]
            w = log.state[:, 12]
            free, resp = {}, {}
            for c in {float(c_ref), *map(float, decays)}:
                phi = float(np.exp(-c * log.dt_s))
                gam = log.dt_s if c == 0 else (1.0 - phi) / c
                free[c] = w[idx + 1] - phi ** np.arange(1, H + 1)[None, :] * w[starts][:, None]   # (W, H)
                for key, u in drive.items():     # the response to a unit gain: Σ_j φ^{h−1−j} γ u_{t+j}
                    resp[(c,) + key] = lfilter([gam], [1.0, -phi], u[idx], axis=1)   # x_h = φ x_{h−1} + γ u_h
            rows = [np.abs(free[float(c_ref)]).sum(axis=1)]
            rows += [np.abs(free[c] - g * resp[(c, d, lp)]).sum(axis=1) for c, d, lp, g in settings]
            errs.append(np.stack(rows))
            ts.append(log.t_s[starts])
            fl.append(np.full(starts.size, names.index(log.name)))
    if not errs:
        raise DataError(f"fit_spinup: no flight segment longer than {H} steps")
    return np.concatenate(errs, axis=1), np.concatenate(ts), np.concatenate(fl), settings


def _best(err: np.ndarray, regimes: int, held: np.ndarray) -> int:
    """Index of the setting (rows 1.. of ``err``) with the lowest worst-regime ratio to the decay
    (row 0), regimes by the held yaw error ``held``; the first (smallest gain) wins a tie."""
    cls = regime_of(held, regimes)
    onehot = (cls[:, None] == np.unique(cls)[None, :]).astype(float)
    with np.errstate(over="ignore", invalid="ignore"):   # a setting whose error overflows is never chosen
        means = (err @ onehot) / onehot.sum(axis=0)                      # (S + 1, regimes)
        worst = (means[1:] / np.maximum(means[:1], 1e-300)).max(axis=1)
    worst = np.where(np.isfinite(worst), worst, np.inf)
    if not np.isfinite(worst).any():
        return 0
    return int(np.flatnonzero(worst <= worst.min() * (1.0 + 1e-12))[0])    # the first (smallest gain) of a tie


def _held(logs: Sequence[StateLog], horizon: int, stride: int) -> np.ndarray:
    """Each window's yaw SimErr with the rate held (the regimes' measure), in _spinup_errors's order."""
    H = int(horizon)
    out = []
    for log in logs:
        for a, b in segment_bounds(log, H + 1):
            if b - a <= H:
                continue
            starts = a + np.arange(0, b - a - H, stride)
            w = log.state[:, 12]
            out.append(np.abs(w[starts[:, None] + np.arange(1, H + 1)[None, :]] - w[starts][:, None]).sum(axis=1))
    return np.concatenate(out) if out else np.zeros(0)


def fit_spinup(logs: Sequence[StateLog], layout: RotorLayout, damping_per_s: float, *, rad_s_per_rpm: float,
               decays=None, delays=SPINUP_DELAYS, lowpass=SPINUP_LOWPASS_S, gains=SPINUP_GAINS,
               horizon: int = 50, stride: int = 5, regimes: int = 4) -> Spinup:
    """The yaw spin-up rung on training flights (module docstring): its decay (from ``decays``,
    default :func:`_decays` of ``damping_per_s``), alignment, motor lag and gain with the lowest
    worst-regime ratio of the yaw SimErr to the decay rung's (``damping_per_s``)."""
    decays = _decays(damping_per_s) if decays is None else decays
    err, _, _, settings = _spinup_errors(logs, layout, float(damping_per_s), rad_s_per_rpm, decays, delays,
                                         lowpass, gains, horizon, stride)
    return Spinup(*_pick(settings, _best(err, regimes, _held(logs, horizon, stride))))


def _decays(c: float) -> tuple[float, ...]:
    """The spin-up rung's own decays tried about the decay rung's ``c`` (1/s): half, the same,
    twice (the reaction moves some of what the decay absorbed)."""
    return tuple(sorted({0.5 * float(c), float(c), 2.0 * float(c)}))


def _pick(settings, i: int) -> tuple[int, float | None, float, float]:
    c, d, lp, g = settings[i]
    return d, lp, g, c


def spinup_folds(logs: Sequence[StateLog], layout: RotorLayout, decays: dict[str, np.ndarray], *,
                 rad_s_per_rpm: float, horizon: int = 50, stride: int = 5, regimes: int = 4) -> dict[str, Spinup]:
    """{flight name: :func:`fit_spinup` on every other flight against that fold's yaw decay
    ``decays[name][2]``}: the windows' errors are computed once per distinct decay and each fold
    chooses on the other flights' windows."""
    names = list(dict.fromkeys(log.name for log in logs))
    held = _held(logs, horizon, stride)
    cache, out = {}, {}
    for j, name in enumerate(names):
        c = float(decays[name][2])
        if c not in cache:
            cache[c] = _spinup_errors(logs, layout, c, rad_s_per_rpm, _decays(c), SPINUP_DELAYS, SPINUP_LOWPASS_S,
                                      SPINUP_GAINS, horizon, stride)
        err, _, flight, settings = cache[c]
        keep = flight != j
        if not keep.any():
            raise DataError(f"fit_spinup: no flight segment longer than {int(horizon)} steps besides {name}")
        out[name] = Spinup(*_pick(settings, _best(err[:, keep], regimes, held[keep])))
    return out


def spinup_interval(logs: Sequence[StateLog], layout: RotorLayout, chosen: Spinup, damping_per_s: float, *,
                    rad_s_per_rpm: float, horizon: int = 50, stride: int = 5, regimes: int = 4,
                    n_boot: int = N_BOOT, seed: int = 0, level: float = 0.95) -> tuple[float, float]:
    """The ``level`` percentile interval of the spin-up gain over a block bootstrap, as
    :func:`droneid.rotation.decay.damping_interval`: every contiguous time block of every flight
    is one unit, resampled with replacement ``n_boot`` times, the gain (with the rung's decay)
    chosen again on each replicate at the ``chosen`` alignment and motor lag, against the decay
    rung's ``damping_per_s``. Grid values: an upper bound at the grid's top means "that much or
    more"."""
    c = float(damping_per_s)
    err, t, flight, settings = _spinup_errors(logs, layout, c, rad_s_per_rpm, _decays(c), (chosen.delay_steps,),
                                              (chosen.lowpass_tau_s,), SPINUP_GAINS, horizon, stride)
    held = _held(logs, horizon, stride)
    units = time_blocks(t, flight)
    rows = [np.flatnonzero(units == u) for u in np.unique(units)]
    rng = np.random.default_rng(seed)
    picks = np.empty(int(n_boot))
    for i in range(int(n_boot)):
        pick = np.concatenate([rows[j] for j in rng.integers(0, len(rows), len(rows))])
        picks[i] = settings[_best(err[:, pick], regimes, held[pick])][3]
    a = 100 * (1 - level) / 2
    return float(np.percentile(picks, a, method="lower")), float(np.percentile(picks, 100 - a, method="higher"))
