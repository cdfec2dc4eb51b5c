"""The vehicle's torque gains (issue 37.4): how hard each body axis answers its motors, as a
constant of the vehicle, with its interval and its test across flights.

The torque rung's terms (:data:`droneid.rotation.choice.DEFAULT_CANDIDATES`), fitted at the equation
level on the training flights, ``ω̇_k = a_k (P s)_k + … + b_k,flight``, give per body axis the gain ``a_k``: the rotors' torque over the body's inertia, in
rad/s² per unit of ``(P s)_k`` (``s_i = (ω_i / 1000 rad/s)²``, ``P`` the layout's torque patterns;
on a command-driven vehicle ``s_i`` is the rotor's thrust as a fraction of full thrust). Whether an
axis's open-loop model uses it is the ladder's decision (:mod:`droneid.rotation.choice`); the gain
is what a controller designer needs either way, and like the v̇ constants
(:mod:`droneid.fitting.constancy`, the same functions) it must hold from flight to flight:

Two conditions of each flight are estimated on that flight alone (:func:`flight_conditions`), as
a clock offset is: the **alignment** of its motor stream (0-60 ms: the rotor speeds read that much
earlier) and the **band** its gain is read in (the moving average over ± 0.05-1 s taken off both
sides of the equation, or none). The slow part of a flight's motor differences is the controller
holding moments the model lacks (the rotor drag moment off its linear law, the centre of gravity,
a trim that wanders within a flight), which move with the trajectory and pull an equation-error
gain towards zero; a filter applied to both sides keeps the equation for what is left. Each flight
takes the (alignment, band) where the torque pattern explains most of its rate changes (the
largest partial R² of the pattern, summed over the axes). The rotor speeds are read as logged (no
low-pass: a filter on one side only would inflate a gain read at high frequency).

- **pooled**: one fit of every training flight, a trim per in-flight stretch (a flight condition:
  balance point, battery); its 95 % interval is the percentile block bootstrap over (flight, time
  block) units (:func:`droneid.dataset.validation.time_blocks`), each replicate refit with its
  trims;
- **per flight**: each flight alone (its own trims; the gain without its bound, as every constancy test's units:
  :func:`droneid.fitting.constancy.unit_bounds`), with its block-bootstrap standard error;
- **constancy**: Cochran's Q over the flights read as Welch's test (each flight's standard error on
  its blocks' degrees of freedom), Holm over the three axes at
  :data:`droneid.fitting.constancy.ALPHA`, and a spread τ of at least
  :data:`~droneid.fitting.constancy.MIN_TAU_REL` of the gain (:func:`~droneid.fitting.constancy.constancies`);
- **the reported interval**: the hull of the pooled bootstrap's and the between-flight
  (random-effects, HKSJ) one, so it counts how much the flights disagree;
- **on the test flights** (:func:`check_gains`; reported, never chosen on): each flight's own gain,
  at its own alignment and band,
  against what a new flight of the vehicle should give, the rule of ``predict``'s check of the v̇
  constants (:func:`droneid.fitting.constancy.new_flight_expectation`, two-sided p, Holm over the
  axes, the spread rule).

The physics bound: a gain is never negative (the torque along the layout's pattern turns the body
the pattern's way; :func:`droneid.rotation.model.rotation_bounds`). An equation-error gain of a
vehicle flown in closed loop is not free of the controller: the motor differences also follow the
rotation they react to (docs/use-the-model.md), which is one reason it can move between flights.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from priors.torque import RotorLayout

from droneid.core.io_util import to_jsonable
from droneid.core.regression import (gram_bounded_lstsq_many, group_grams, held_factor, huber_factor,
                                     robust_fit_grouped, within_gram)
from droneid.dataset.validation import time_blocks
from droneid.errors import DataError
from droneid.fitting.constancy import (ALPHA, MIN_UNIT_ROWS, Constancy, constancies, holm_flags, moved,
                                       new_flight_expectation, new_flight_p, unit_bounds, unit_estimate)
from droneid.rotation.commands import CommandSpeeds
from droneid.rotation.model import (AXIS_NAMES, RotationModel, fit_rotation, rotation_bounds, rotation_design,
                                    rotation_rows)
from droneid.simulation.openloop import StateLog

__all__ = ["TorqueGains", "torque_gains", "check_gains", "flight_conditions", "N_BOOT", "IDENTIFIABLE_REL",
           "MAX_ALIGN_S", "BANDS_S"]

#: bootstrap replicates of the pooled gain
N_BOOT = 200
#: a test flight's gain whose 95 % interval is wider than ± this fraction of what a new flight
#: should give is not identifiable there (the v̇ constants' rule,
#: :data:`droneid.fitting.terms.IDENTIFIABLE_REL`, floors that scale at 1 because those are scales
#: near 1; a gain has its own scale)
IDENTIFIABLE_REL = 0.5
#: the alignments of a flight's motor stream tried: 0 to MAX_ALIGN_S in steps of 1/ALIGN_SUBSTEPS
#: of the grid step (the rotor speeds interpolated linearly between samples: one whole step moves a
#: flight's gain by 10-25 % on the shared squares)
MAX_ALIGN_S = 0.06
ALIGN_SUBSTEPS = 4
#: the bands tried: the half-width (s) of the moving average taken off both sides, None: none
#: (±0.05 s is the narrowest above the smoothing kernel's ±2 steps at 100 Hz)
BANDS_S = (None, 0.05, 0.1, 0.2, 0.5, 1.0)


@dataclass(frozen=True)
class TorqueGains:
    """result.json's ``rotation.torque_gains``.

    unit : the gains' unit; terms : the torque model's other terms (fitted beside the gain);
    gains : {axis: (value, low, high)} the pooled gain and its reported 95 % interval (the hull of
        the pooled block bootstrap and the between-flight interval); pooled_interval : {axis:
        (low, high)} the bootstrap's alone; constancy : {axis: :class:`Constancy`} (empty with
        fewer than two flights long enough to fit alone); model : how the rotor speeds are read (the
        layout, the torque rung's terms, ``commands`` on a command-driven vehicle; its
        coefficients are zero: the gains are ``gains``, and a chosen torque rung has its own,
        fitted for open-loop prediction); tested : {test flight: {axis:
        (value, low, high, p, holds)}} from :func:`check_gains` (holds None: not identifiable there);
        conditions : {flight: (alignment s, band half-width s or None)} of every flight read, training
        and test (:func:`flight_conditions`)
    """
    unit: str
    terms: tuple[str, ...]
    gains: Mapping[str, tuple[float, float, float]]
    pooled_interval: Mapping[str, tuple[float, float]]
    constancy: Mapping[str, Constancy] = field(default_factory=dict)
    model: RotationModel | None = None
    tested: Mapping[str, Mapping[str, tuple]] = field(default_factory=dict)
    conditions: Mapping[str, tuple[float, float | None]] = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-able (docs/result-json.md, ``rotation.torque_gains``)."""
        return to_jsonable({"unit": self.unit, "terms": list(self.terms),
                            "gains": {k: list(v) for k, v in self.gains.items()},
                            "pooled_interval": {k: list(v) for k, v in self.pooled_interval.items()},
                            "constancy": {k: c.to_dict() for k, c in self.constancy.items()},
                            "model": None if self.model is None else self.model.to_dict(),
                            "tested": {f: {a: list(v) for a, v in per.items()} for f, per in self.tested.items()},
                            "conditions": {f: {"align_s": a, "band_s": b} for f, (a, b) in self.conditions.items()}})

    def text(self) -> str:
        """Each axis's gain and its 95 % interval, for people: "roll 52.7 [47.3, 58.7], …"."""
        return ", ".join(f"{ax} {v:.3g} [{lo:.3g}, {hi:.3g}]" for ax, (v, lo, hi) in self.gains.items())

    def failing(self) -> list[str]:
        """"flight axis" of every test flight's gain that does not hold."""
        return [f"{f} {ax}" for f, per in self.tested.items() for ax, v in per.items() if v[4] is False]

    def verdict(self) -> str:
        """Whether the gains hold across the training flights and on the test flights, in words
        (an axis that could not be tested is said so, never counted as holding)."""
        flagged = [ax for ax, c in self.constancy.items() if c.constant is False]
        tested = [ax for ax, c in self.constancy.items() if c.constant is not None]
        said = (f"NOT constant over the training flights on {', '.join(flagged)}" if flagged else
                "constant over the training flights" if tested else "untested across flights")
        if self.tested:
            judged = [v for per in self.tested.values() for v in per.values() if v[4] is not None]
            bad = self.failing()
            said += (f"; DO NOT HOLD on the test flights ({', '.join(bad)})" if bad else
                     ("; the test flights lie within the training flights' spread" if flagged else
                      "; hold on the test flights") if judged else "; not identifiable on the test flights")
        return said

    @classmethod
    def from_dict(cls, d: Mapping) -> "TorqueGains":
        try:
            def nums(v):
                return tuple(math.nan if x is None else float(x) for x in v)
            return cls(str(d["unit"]), tuple(d["terms"]), {k: nums(v) for k, v in d["gains"].items()},
                       {k: nums(v) for k, v in d["pooled_interval"].items()},
                       {k: Constancy.from_dict(c) for k, c in (d.get("constancy") or {}).items()},
                       None if d.get("model") is None else RotationModel.from_dict(d["model"]),
                       {f: {a: (*nums(v[:4]), v[4]) for a, v in per.items()} for f, per in (d.get("tested") or {}).items()},
                       {f: (float(c["align_s"]), None if c["band_s"] is None else float(c["band_s"]))
                        for f, c in (d.get("conditions") or {}).items()})
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(f"the result's torque gains are damaged: {exc}") from None


def torque_gains(logs: Sequence[StateLog], layout: RotorLayout, candidate: Mapping, *, rad_s_per_rpm: float,
                 unit: str, window_s: float = 0.05, seed: int = 0, n_boot: int = N_BOOT,
                 commands: CommandSpeeds | None = None) -> TorqueGains:
    """The torque gains of ``logs`` (training flights' in-flight stretches; stretches of one flight
    share its name; a command-driven vehicle's already its commands' speeds, ``commands`` the
    motor model they came through) under the torque ``candidate``'s terms (keywords of
    :func:`droneid.rotation.model.fit_rotation`; its input conditioning is not used); see the
    module docstring. ``window_s``: the Savitzky-Golay window (s) of the rows' screening.
    DataError without a row in flight."""
    cand = {**dict(candidate), "lowpass_tau_s": None, "balance_weight_s": None, "delay_steps": 0}
    shell = fit_rotation(logs, layout, window_s=window_s, rad_s_per_rpm=rad_s_per_rpm, **cand)
    terms = shell.terms
    conditions = flight_conditions(logs, shell, window_s)
    rows = _rows(logs, shell, window_s, conditions)
    flight, group, t = rows["flight"], rows["group"], rows["t"]
    names = rows["names"]
    blocks = time_blocks(t, flight)
    used = [f for f in range(len(names)) if np.count_nonzero(flight == f) >= MIN_UNIT_ROWS]
    pooled, boot, vals, ses, dfs, ivs = {}, {}, np.zeros((len(used), 3)), np.zeros((len(used), 3)), \
        np.zeros(len(used)), [np.zeros((2, 3)) for _ in used]
    for k, axis in enumerate(AXIS_NAMES):
        A, y = rows["A"][k], rows["y"][k]
        lo = rotation_bounds(k, terms, A.shape[1])
        fit = robust_fit_grouped(A, y, group, lo=lo)
        pooled[axis] = float(fit.beta[0])
        draws = held_factor(_grouped_draws(A, y, group, blocks, fit.weights, lo, n_boot, seed),
                            fit.beta[:A.shape[1]], huber_factor(fit), lo)[:, 0]
        boot[axis] = tuple(float(x) for x in np.percentile(draws, [2.5, 97.5]))
        for i, f in enumerate(used):       # each flight alone, its gain unbounded (unit_bounds: a test of agreement)
            beta, se, pct, dfs[i] = _alone(A, y, group, t, flight == f, _unbounded(lo), seed)
            vals[i, k], ses[i, k], ivs[i][:, k] = beta[0], se[0], pct[:, 0]
    const = constancies("flight", [names[f] for f in used], vals, ses, ivs, dict(enumerate(AXIS_NAMES)), dfs=dfs)
    gains = {}
    for axis in AXIS_NAMES:
        lo_, hi_ = boot[axis]
        c = const.get(axis)
        if c is not None and c.between is not None:
            lo_, hi_ = min(lo_, c.between[0]), max(hi_, c.between[1])
        gains[axis] = (pooled[axis], max(lo_, 0.0), hi_)
    zero = dataclasses.replace(shell, coef=tuple(np.zeros_like(c) for c in shell.coef), trim=np.zeros(3),
                               flight_trims=np.zeros((0, 3)), commands=commands)
    return TorqueGains(unit, tuple(terms), gains, boot, const, model=zero, conditions=conditions)


def check_gains(g: TorqueGains, logs: Sequence[StateLog], *, window_s: float = 0.05, seed: int = 0) -> TorqueGains:
    """``g`` with each flight of ``logs`` (test flights' in-flight stretches, as logged: a
    command-driven vehicle's are read through ``g.model.commands``) tested: its own gain per axis
    (fitted alone with its trims, the other terms within their bounds, as a training flight's) against what a new
    flight of the vehicle should give (:func:`droneid.fitting.constancy.new_flight_expectation` of
    the reported gain and its constancy), two-sided p, Holm over the axes at ALPHA, the spread rule;
    each flight's gain unbounded, as the training flights' (:func:`droneid.fitting.constancy.unit_bounds`);
    a gain whose interval is wider than ±:data:`IDENTIFIABLE_REL` of what a new flight should give
    (a width rule independent of the flight's own value) is not identifiable there (holds None, as
    when its p is not finite). Reported, never chosen on.
    ``window_s`` as :func:`torque_gains`."""
    shell = g.model
    if shell is None or not logs:
        return g
    if shell.commands is not None:
        logs = [shell.commands.speed_log(log) for log in logs]
    conditions = flight_conditions(logs, shell, window_s)
    rows = _rows(logs, shell, window_s, conditions)
    tested = {}
    for f, name in enumerate(rows["names"]):
        sel = rows["flight"] == f
        if np.count_nonzero(sel) < MIN_UNIT_ROWS:
            continue
        res, ps = {}, {}
        for k, axis in enumerate(AXIS_NAMES):
            lo = _unbounded(rotation_bounds(k, shell.terms, rows["A"][k].shape[1]))
            beta, se, pct, dof = _alone(rows["A"][k], rows["y"][k], rows["group"], rows["t"], sel, lo, seed)
            v, low, high = float(beta[0]), float(pct[0, 0]), float(pct[1, 0])
            c = g.constancy.get(axis)
            expected = new_flight_expectation(g.gains[axis][0], *g.pooled_interval[axis],
                                              None if c is None else c.to_dict())
            res[axis] = (v, low, high)
            p = new_flight_p(v, float(se[0]), expected, dof)
            if 0 < (high - low) / 2 <= IDENTIFIABLE_REL * abs(expected["value"]) and math.isfinite(p):
                ps[axis] = p
                res[axis] += (expected["value"],)
        flags = holm_flags(ps, ALPHA)
        tested[name] = {axis: (*res[axis][:3], ps[axis], not moved(flags[axis], abs(res[axis][0] - res[axis][3]),
                                                                    res[axis][3]))
                        if axis in ps else (*res[axis], math.nan, None) for axis in AXIS_NAMES}
    return dataclasses.replace(g, tested=tested, conditions={**g.conditions, **conditions})


#: the smoothing applied alike to the target and to every regressor (a linear filter on both sides
#: keeps the equation exact): triangular, 5 steps
_KERNEL = np.array([1.0, 2.0, 3.0, 2.0, 1.0]) / 9.0


def _dt(logs: Sequence[StateLog]) -> float:
    """The logs' grid step (s): their median."""
    return float(np.median([log.dt_s for log in logs]))


def flight_conditions(logs: Sequence[StateLog], shell: RotationModel, window_s: float
                      ) -> dict[str, tuple[float, float | None]]:
    """{flight: (alignment in s, band half-width in s or None)} of each flight of ``logs``
    (stretches of one flight share its name), chosen on that flight alone (module docstring):
    the pair where the torque pattern's partial R² (ordinary least squares with a trim per
    stretch, with and without the pattern), summed over the axes, is largest. Alignments from 0
    to :data:`MAX_ALIGN_S` in 1/:data:`ALIGN_SUBSTEPS` of the grid step."""
    dt = _dt(logs)
    aligns = [round(i * dt / ALIGN_SUBSTEPS, 6) for i in range(int(round(MAX_ALIGN_S / dt)) * ALIGN_SUBSTEPS + 1)]
    out = {}
    for name in dict.fromkeys(log.name for log in logs):
        which = [log for log in logs if log.name == name]
        bases = [_base(log, shell, window_s) for log in which]
        best = None
        for a in aligns:
            rows = [_log_rows(log, shell, b, a) for log, b in zip(which, bases)]
            for band in BANDS_S:
                parts = [_filtered(r, band, log.dt_s) for r, log in zip(rows, which)]
                score = sum(_partial_r2(np.vstack([p[0][k] for p in parts]), np.concatenate([p[1][k] for p in parts]),
                                        np.concatenate([np.full(p[1][k].size, i) for i, p in enumerate(parts)]))
                            for k in range(3))
                if best is None or score > best[0]:
                    best = (score, a, band)
        out[name] = (best[1], best[2])
    return out


def _partial_r2(A: np.ndarray, y: np.ndarray, group: np.ndarray) -> float:
    """The share of the residual sum of squares the first column of ``A`` removes, in an ordinary
    least squares with a free intercept per ``group`` (0 without rows)."""
    if y.size <= A.shape[1] + 2:
        return 0.0
    D = (group[:, None] == np.unique(group)[None]).astype(float)
    X = np.column_stack([A, D])
    scale = np.maximum(np.sqrt(np.sum(X * X, axis=0)), 1e-300)       # the normal equations, columns scaled
    X = X / scale
    G, c, yy = X.T @ X, X.T @ y, float(y @ y)

    def rss(cols):
        b = np.linalg.lstsq(G[np.ix_(cols, cols)], c[cols], rcond=1e-12)[0]
        return max(yy - float(b @ c[cols]), 0.0)
    full, without = rss(np.arange(X.shape[1])), rss(np.arange(1, X.shape[1]))
    return 1.0 - full / without if without > 0 else 0.0


def _base(log: StateLog, shell: RotationModel, window_s: float) -> tuple:
    """What of one stretch's rows does not depend on the alignment: :func:`rotation_rows` of it
    and each axis's smoothed rate change over each step (module docstring)."""
    dw = np.diff(log.state[:, 10:13], axis=0) / log.dt_s
    return rotation_rows(log, shell, window_s), [_smooth(dw[:, k:k + 1])[:, 0] for k in range(3)]


def _log_rows(log: StateLog, shell: RotationModel, base: tuple, align_s: float = 0.0
              ) -> tuple[np.ndarray, list, list]:
    """One stretch's rows before the band filter: the rows kept (in flight, the kernel inside the
    stretch, none whose aligned rotor speeds would start before the stretch), each axis's smoothed
    design at every step midpoint and its smoothed rate change over the step (``base``:
    :func:`_base` of the stretch). ``align_s``: the rotor speeds read that much earlier (s; linear
    between samples)."""
    r, dw = base
    if align_s > 0 and log.rpm.shape[0]:
        t = np.asarray(log.t_s, float)
        rpm = np.column_stack([np.interp(t - align_s, t, log.rpm[:, m]) for m in range(log.rpm.shape[1])])
        s, rate = shell.conditioned(rpm, log.dt_s)
        r = (r[0], s[:-1], r[2], rate[:-1], *r[4:])
    every = (np.ones_like(r[0]), *r[1:])
    keep = np.flatnonzero(np.convolve(r[0].astype(float), np.ones(_KERNEL.size), mode="same") >= _KERNEL.size - 1e-9)
    keep = keep[keep >= math.ceil(align_s / log.dt_s - 1e-9) + _KERNEL.size // 2]
    P = shell.layout.patterns()
    return keep, [_smooth(rotation_design(k, P, shell.terms, every)) for k in range(3)], dw


def _filtered(rows: tuple, band: float | None, dt_s: float) -> tuple[list, list]:
    """(designs, targets) per axis of :func:`_log_rows`'s rows at the kept rows, with the moving
    average over ± ``band`` seconds taken off both sides (None: as they are)."""
    keep, A, y = rows
    widths = np.cumsum([0, *(a.shape[1] for a in A)])
    both = _highpass(np.column_stack([*A, *y]), band, dt_s)[keep]           # one pass over every column
    return [both[:, widths[k]:widths[k + 1]] for k in range(3)], [both[:, widths[-1] + k] for k in range(3)]


def _highpass(x: np.ndarray, band: float | None, dt_s: float) -> np.ndarray:
    """``x`` (N, K) less its centred moving average over ± ``band`` s (shortened to fit the
    stretch); ``x`` itself for None."""
    if band is None or x.shape[0] < 3:
        return x
    n = min(max(int(round(band / dt_s)), 1), (x.shape[0] - 1) // 2)
    cs = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])   # moving sums from cumulative sums
    i = np.arange(x.shape[0])
    lo, hi = np.maximum(i - n, 0), np.minimum(i + n + 1, x.shape[0])  # the average over what lies inside
    return x - (cs[hi] - cs[lo]) / (hi - lo)[:, None]


def _rows(logs: Sequence[StateLog], shell: RotationModel, window_s: float,
          conditions: Mapping[str, tuple[float, float | None]]) -> dict:
    """Every axis's design and target over ``logs``, each flight at its ``conditions``
    (:func:`flight_conditions`), and per row its flight (index into ``names``: stretches of one
    flight share its name), stretch (``group``) and a time index (``t``, steps; stretches far
    apart).

    The target is each step's rate change over the step, ``(ω_{k+1} − ω_k) / dt``, at the step's
    midpoint where the regressors sit (the input held over the step, the states at the midpoint):
    exact for the integral of ω̇ over the step, and white gyro noise in it is uncorrelated with the
    midpoint rate of the decay term. Both sides are then smoothed by one filter (:data:`_KERNEL`),
    which keeps the equation. (A Savitzky-Golay derivative of the rates against unsmoothed
    regressors, as the open-loop fit takes it, attenuates the gains: 1 % on the planted flights of
    tests/unit/test_torque_gains.py, more than their intervals.)"""
    names = list(dict.fromkeys(log.name for log in logs))
    A, y = [[], [], []], [[], [], []]
    flight, group, t = [], [], []
    for j, log in enumerate(logs):
        align, band = conditions[log.name]
        rows = _log_rows(log, shell, _base(log, shell, window_s), align)
        keep = rows[0]
        Aj, yj = _filtered(rows, band, log.dt_s)
        for k in range(3):
            A[k].append(Aj[k])
            y[k].append(yj[k])
        flight.append(np.full(keep.size, names.index(log.name)))
        group.append(np.full(keep.size, j))
        t.append(keep + 1e7 * j)
    return {"names": names, "flight": np.concatenate(flight), "group": np.concatenate(group),
            "t": np.concatenate(t).astype(float), "A": [np.vstack(a) for a in A], "y": [np.concatenate(v) for v in y]}


def _smooth(x: np.ndarray) -> np.ndarray:
    """Each column of ``x`` (N, K) filtered by :data:`_KERNEL` (centred; the ends left partial)."""
    return np.column_stack([np.convolve(x[:, c], _KERNEL, mode="same") for c in range(x.shape[1])])


def _unbounded(lo: np.ndarray) -> np.ndarray:
    """The lower bounds ``lo`` of a flight's own fit of the torque terms (no upper bounds) as every
    constancy test's units take them (:func:`droneid.fitting.constancy.unit_bounds`): the gain (the
    first column) unbounded, the other terms keep theirs."""
    return unit_bounds(lo, np.full_like(np.asarray(lo, float), np.inf), tested=[0])[0]


def _alone(A: np.ndarray, y: np.ndarray, group: np.ndarray, t: np.ndarray, sel: np.ndarray, lo: np.ndarray,
           seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(β, se, pct, df)`` of :func:`droneid.fitting.constancy.unit_estimate` of the rows ``sel`` (one
    flight), a trim per stretch of it, bootstrapped over its own time blocks."""
    stretches = np.unique(group[sel])
    A1 = np.column_stack([A[sel], (group[sel][:, None] == stretches[None]).astype(float)])
    lo1 = np.concatenate([lo, np.full(stretches.size, -np.inf)])
    fit, se, pct, dof = unit_estimate(A1, y[sel], time_blocks(t[sel], np.zeros(int(sel.sum()), int)), lo1, seed=seed)
    return fit.beta, se, pct, dof


def _grouped_draws(A: np.ndarray, y: np.ndarray, group: np.ndarray, blocks: np.ndarray, w: np.ndarray,
                   lo: np.ndarray, n_boot: int, seed: int) -> np.ndarray:
    """(n_boot, k) coefficients of ``y ≈ A β + b_group`` refit on block-bootstrap replicates: the
    (flight, block) units ``blocks`` resampled with replacement, the rows keeping the full fit's
    robust weights ``w``, each replicate's intercepts (one per ``group``) profiled out."""
    g_ids, g_inv = np.unique(group, return_inverse=True)
    b_ids, b_inv = np.unique(blocks, return_inverse=True)
    cell = b_inv * g_ids.size + g_inv                     # a unit cut where it spans two stretches
    c_ids, S = group_grams(A, y, w, cell)
    c_block, c_group = c_ids // g_ids.size, c_ids % g_ids.size
    rng = np.random.default_rng(seed)
    counts = np.stack([np.bincount(d, minlength=b_ids.size)
                       for d in rng.integers(0, b_ids.size, (n_boot, b_ids.size))]).astype(float)
    within = np.empty((n_boot, A.shape[1] + 1, A.shape[1] + 1))
    for r in range(n_boot):
        Sg = np.zeros((g_ids.size, *S.shape[1:]))
        np.add.at(Sg, c_group, counts[r, c_block][:, None, None] * S)
        within[r] = within_gram(Sg)
    return gram_bounded_lstsq_many(within, lo)
