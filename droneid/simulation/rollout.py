"""Multi-step (open-loop) prediction: integrate identified translational models along a flight.

The metric (``docs/use-the-model.md`` states it for comparison with other benchmarks):

* **State.** Only the world velocities of the axes a model set covers (``vx`` for ``vx_dot``,
  ...) are predicted, plus, for the position error, the displacement they integrate to. Every
  other signal a model reads (roll, pitch, yaw, motor speeds / commands, throttle, battery
  voltage, the velocity of an axis the set does not model, ...) is TAKEN FROM THE LOG at the
  time it is needed, linearly interpolated (angles unwrapped), at ``t − delays_s[signal]``.
* **Starts.** Every sample of the reference velocity signal (the first modelled axis, at its
  native rate) inside the in-flight intervals of :func:`droneid.dataset.builder.in_flight_intervals`.
  The initial velocity is the logged one at the start; the initial position is the logged one.
* **Integration.** Classic RK4 with step ``dt_s`` (default: the median period of the
  reference velocity signal, 0.01 s for a 100 Hz log); inputs at the step's start, middle and end.
* **Horizon h.** The prediction ``h`` steps (``h·dt_s`` seconds) after the start is compared with
  the log at that time (interpolated when ``dt_s`` is not the native period). A start counts for
  horizon ``h`` when ``[t0, t0 + h·dt_s]`` lies inside one in-flight interval and inside the span
  of every signal used (shifted by its delay) and crosses no gap of any of them (a gap: more than
  5 median periods between samples, as :class:`droneid.dataset.builder.DatasetBuilder` with
  ``max_gap_s=0``) nor a hole of a screened implausible sample or jump (:mod:`droneid.logs.screening`);
  other starts are skipped and counted.
* **Errors.** Per axis: ``sqrt(mean_k (v̂_a(t_k + h·dt) − v_a(t_k + h·dt))²)`` in m/s over the
  starts ``k`` valid for ``h``, all flights pooled. Position: ``sqrt(mean_k ‖p̂ − p‖²)`` in m over
  the modelled axes when at least the two horizontal axes are modelled and the log has positions.
  Non-finite predictions (a model blowing up) are counted per model and horizon, not averaged.
* **Constant-velocity baseline.** ``v̂(t0 + h·dt) = v(t0)``, ``p̂ = p(t0) + v(t0)·h·dt``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from droneid.dataset.builder import signal_gaps, with_euler_from_quaternion, in_flight_intervals, resample_signal
from droneid.errors import ConfigError, DataError, MissingSignalError
from droneid.core.expressions import compile_expression
from droneid.logs.flight import Flight
from droneid.logs.screening import screen_signal
from droneid.simulation.rk4 import rk4_step
from droneid.fitting.closed_form import IdentifiedModel
from droneid.core.targets import TARGETS

__all__ = ["RolloutResult", "RolloutSegment", "rollout_errors", "sample_inputs", "horizon_section",
           "CONSTANT_VELOCITY", "AXES"]

#: name of the baseline model set that keeps the start velocity
CONSTANT_VELOCITY = "constant velocity"
#: the translational axes, as rollout walks them: velocity signal -> (target, position signal)
#: (a view of :data:`droneid.core.targets.TARGETS`)
AXES = {t.velocity: (t.name, t.position) for t in TARGETS.values()}


def sample_inputs(flight: Flight, names: Sequence[str], t, delays_s: Mapping[str, float] | None = None,
                  clip: bool = False) -> dict[str, np.ndarray]:
    """The flight's signals ``names`` at times ``t`` (s, any shape), each read at ``t − delay``
    (``delays_s``: {signal: s}); linear interpolation, angles unwrapped; nan outside a signal's span
    (``clip``: the first / last value instead, for times the caller has already checked).
    Raises MissingSignalError for a signal the flight lacks."""
    t = np.asarray(t, float)
    delays_s = delays_s or {}
    out = {}
    for n in names:
        if not flight.has(n):
            raise MissingSignalError(n, flight.names, where=f"flight '{flight.name}'")
        sig = flight[n]
        tt = (t - float(delays_s.get(n, 0.0))).ravel()
        if clip:
            tt = np.clip(tt, sig.start_s, sig.end_s)
        out[n] = resample_signal(sig, tt).reshape(t.shape)
    return out


@dataclass(frozen=True)
class RolloutSegment:
    """One predicted trace: times ``t`` (s, flight time base), the logged velocities ``measured``
    {axis: (H+1,) m/s} and every model's predictions ``predicted`` {model: {axis: (H+1,)}}."""
    flight: str
    t: np.ndarray
    measured: Mapping[str, np.ndarray]
    predicted: Mapping[str, Mapping[str, np.ndarray]]


@dataclass(frozen=True)
class RolloutResult:
    """Multi-step prediction errors (see the module docstring for the metric).

    horizons : steps; dt_s : step (s); axes : {model: modelled velocity axes};
    position_axes : {model: position axes of its position error (empty: none)};
    rmse : {model: {h: {"vx", "vy", "vz", "position"}}} in m/s (velocities) and m (position),
    only the axes the model covers; n_starts / skipped : {h: count}; nonfinite : {model: {h: count}};
    segments : a few predicted traces for plots; notes : what was done;
    states : with ``keep_states``, that model's simulated states {h: {column: (n_h,) array}} at every start
    valid for ``h`` (:func:`rollout_errors`; not part of :meth:`to_dict`).
    """
    horizons: tuple[int, ...]
    dt_s: float
    axes: Mapping[str, tuple[str, ...]]
    position_axes: Mapping[str, tuple[str, ...]]
    rmse: Mapping[str, Mapping[int, Mapping[str, float]]]
    n_starts: Mapping[int, int]
    skipped: Mapping[int, int]
    nonfinite: Mapping[str, Mapping[int, int]]
    segments: tuple[RolloutSegment, ...] = ()
    notes: tuple[str, ...] = field(default_factory=tuple)
    states: Mapping[int, Mapping[str, np.ndarray]] | None = field(default=None, repr=False, compare=False)

    def to_dict(self, segments: bool = True) -> dict:
        """Plain data (JSON-able; horizons as string keys); ``segments=False`` leaves the traces out."""
        d = {"dt_s": self.dt_s, "steps": list(self.horizons),
             "seconds": [h * self.dt_s for h in self.horizons],
             "axes": {m: list(a) for m, a in self.axes.items()},
             "position_axes": {m: list(a) for m, a in self.position_axes.items()},
             "rmse": {m: {str(h): dict(e) for h, e in per.items()} for m, per in self.rmse.items()},
             "n_starts": {str(h): n for h, n in self.n_starts.items()},
             "skipped": {str(h): n for h, n in self.skipped.items()},
             "nonfinite": {m: {str(h): n for h, n in per.items()} for m, per in self.nonfinite.items()},
             "notes": list(self.notes)}
        if segments:
            d["segments"] = [{"flight": s.flight, "t": s.t.tolist(),
                              "measured": {a: v.tolist() for a, v in s.measured.items()},
                              "predicted": {m: {a: v.tolist() for a, v in p.items()}
                                            for m, p in s.predicted.items()}} for s in self.segments]
        return d


# -- the computation ----------------------------------------------------------------------------
def _check_models(models) -> dict[str, dict[str, IdentifiedModel]]:
    if not isinstance(models, Mapping) or not models:
        raise ConfigError("rollout needs a non-empty mapping {model name: {target: IdentifiedModel}}")
    out = {}
    for name, per in models.items():
        if name == CONSTANT_VELOCITY:
            raise ConfigError(f"the model name {CONSTANT_VELOCITY!r} is reserved for the baseline")
        per = dict(per or {})
        if not per:
            raise ConfigError(f"model set {name!r} holds no model")
        for target, m in per.items():
            if target not in TARGETS:
                raise ConfigError(f"rollout integrates translational models ({', '.join(TARGETS)}); "
                                  f"model set {name!r} has {target!r}")
            if not isinstance(m, IdentifiedModel) or m.target != target:
                raise ConfigError(f"model set {name!r}: {target} must be an IdentifiedModel of {target}")
            fed_back = [s for s in m.delays_s if s in AXES and _is_state(per, s)]
            if fed_back:
                raise ConfigError(f"model set {name!r}: {target} reads the predicted {fed_back[0]} with a "
                                  f"delay; rollout cannot feed back a delayed state")
        out[str(name)] = per
    return out


def _is_state(per: Mapping[str, IdentifiedModel], signal: str) -> bool:
    """True when ``signal`` (a velocity) is a state of this model set (its target is modelled)."""
    return AXES[signal][0] in per


def _check_horizons(horizons) -> tuple[int, ...]:
    try:
        hs = tuple(sorted({int(h) for h in horizons}))
    except (TypeError, ValueError):
        raise ConfigError(f"The 'horizons' parameter must be positive integers (steps). Got {horizons!r} "
                          f"instead.") from None
    if not hs or hs[0] < 1 or any(float(h) != int(h) for h in horizons):
        raise ConfigError(f"The 'horizons' parameter must be positive integers (steps). Got {horizons!r} "
                          f"instead.")
    return hs


def rollout_errors(models: Mapping[str, Mapping[str, IdentifiedModel]], flights,
                   horizons: Sequence[int] = (1, 10, 50), dt_s: float | None = None,
                   n_segments: int = 6, keep_states: str | None = None) -> RolloutResult:
    """Multi-step prediction errors of each model set against the log, plus the constant-velocity
    baseline (see the module docstring for the exact metric).

    models : {name: {target: IdentifiedModel}} with targets among vx_dot, vy_dot, vz_dot (e.g.
        {"identified": {...}, "empirical": {...}}); flights : a Flight or a sequence of them;
    horizons : steps; dt_s : step in s (default: the reference velocity signal's median period,
        taken from the first flight); n_segments : predicted traces kept for plots; keep_states : the
        name of a model set whose simulated states to keep (``states``: per horizon h, columns
        ``flight``, ``t0_s`` (start, s), ``t_s`` (= t0_s + h·dt_s), the predicted world velocities
        ``vx``.. (m/s) and positions ``x``.. (m) of its modelled axes, and each as logged,
        ``vx_logged``.., at ``t_s``).
    All starts of a flight are integrated at once (arrays over starts)."""
    sets = _check_models(models)
    hs = _check_horizons(horizons)
    if dt_s is not None and (isinstance(dt_s, bool) or not isinstance(dt_s, (int, float))
                             or not math.isfinite(dt_s) or dt_s <= 0):
        raise ConfigError(f"The 'dt_s' parameter must be a positive number of seconds. Got {dt_s!r} instead.")
    flights = [flights] if isinstance(flights, Flight) else list(flights)
    if not flights:
        raise ConfigError("rollout needs at least one flight")
    union = [a for a in AXES if any(AXES[a][0] in per for per in sets.values())]
    ref = union[0]
    names = [*sets, CONSTANT_VELOCITY]
    axes = {**{m: tuple(a for a in AXES if AXES[a][0] in per) for m, per in sets.items()},
            CONSTANT_VELOCITY: tuple(union)}
    H = hs[-1]
    sq = {m: {h: {} for h in hs} for m in names}      # model -> h -> key -> [sum of squares, count]
    nonfinite = {m: {h: 0 for h in hs} for m in names}
    n_starts = {h: 0 for h in hs}
    skipped = {h: 0 for h in hs}
    notes, segments = [], []
    kept: dict[int, list] = {h: [] for h in hs}
    pos_axes: dict[str, tuple[str, ...]] = {}
    for fi, f0 in enumerate(flights):
        f, _ = with_euler_from_quaternion(f0)
        for a in union:
            if not f.has(a):
                raise MissingSignalError(a, f.names, where=f"flight '{f.name}' (the rollout state)")
        if dt_s is None:
            if len(f[ref]) < 2:
                raise DataError(f"flight '{f.name}': {ref} has fewer than two samples")
            dt_s = float(np.median(np.diff(f[ref].t)))
            notes.append(f"step dt = {dt_s:.6g} s: the median period of {ref} in '{f.name}'")
        # the position error needs logged positions of at least the horizontal modelled axes
        if fi == 0:
            for m in names:
                pa = tuple(AXES[a][1] for a in axes[m])
                pos_axes[m] = pa if {"vx", "vy"} <= set(axes[m]) and all(
                    all(g.has(p) for g in flights) for p in pa) else ()
        ivs, _ = in_flight_intervals(f)
        tv = f[ref].t
        inside = np.zeros(tv.size, bool)
        for a, b in ivs:
            inside |= (tv >= a) & (tv <= b)
        t0 = tv[inside]
        if t0.size == 0:
            notes.append(f"'{f.name}': no in-flight samples")
            continue
        # every (signal, delay) read from the log, and the velocity / position references
        reads = {(s, float(m.delays_s.get(s, 0.0))) for per in sets.values() for m in per.values()
                 for s in m.signals if not (s in AXES and _is_state(per, s))}
        checked = reads | {(a, 0.0) for a in union} | {(p, 0.0) for m in names for p in pos_axes[m]}
        ok = {h: np.zeros(t0.size, bool) for h in hs}
        holes: dict[str, list] = {}   # gaps and screened glitches (droneid.logs.screening) of each signal
        tol = 1e-6 * dt_s   # round-off of t0 + h·dt against sample times
        for h in hs:
            t1 = t0 + h * dt_s
            for a, b in ivs:
                ok[h] |= (t0 >= a - tol) & (t1 <= b + tol)
            for s, d in checked:
                if not f.has(s):
                    raise MissingSignalError(s, f.names, where=f"flight '{f.name}' (a model input)")
                sig = f[s]
                ok[h] &= (t0 - d >= sig.start_s - tol) & (t1 - d <= sig.end_s + tol)
                for g0, g1 in holes.setdefault(s, [*signal_gaps(sig, 0.0), *screen_signal(sig).holes]):
                    ok[h] &= ~((t0 - d < g1 - tol) & (t1 - d > g0 + tol))
            n_starts[h] += int(ok[h].sum())
            skipped[h] += int((~ok[h]).sum())
        keep = ok[hs[0]]
        if not keep.any():
            continue
        t0 = t0[keep]
        ok = {h: v[keep] for h, v in ok.items()}
        grid = t0[:, None] + 0.5 * dt_s * np.arange(2 * H + 1)[None, :]     # (n, 2H+1): half steps
        inputs = {}
        for s, d in reads:
            inputs[(s, d)] = sample_inputs(f, [s], grid, {s: d}, clip=True)[s]
        full = grid[:, ::2]
        meas = sample_inputs(f, union, full, clip=True)
        pos = sample_inputs(f, sorted({p for m in names for p in pos_axes[m]}), full, clip=True)
        preds = {}
        for m in names:
            if m == CONSTANT_VELOCITY:
                v = {a: np.repeat(meas[a][:, :1], H + 1, axis=1) for a in axes[m]}
                p = {AXES[a][1]: (pos[AXES[a][1]][:, :1] + meas[a][:, :1] * dt_s * np.arange(H + 1))
                     for a in axes[m] if AXES[a][1] in pos}
            else:
                v, p = _integrate(sets[m], meas, pos, inputs, dt_s, H)
            preds[m] = v
            if m == keep_states:
                for h in hs:
                    kept[h].append(_states(f.name, t0, h, dt_s, ok[h], {**v, **p}, {**meas, **pos}))
            for h in hs:
                sel = ok[h]
                for a in axes[m]:
                    _accumulate(sq[m][h], nonfinite[m], h, a, v[a][sel, h] - meas[a][sel, h], count_bad=True)
                if pos_axes[m]:
                    e2 = sum((p[q][sel, h] - pos[q][sel, h]) ** 2 for q in pos_axes[m])
                    _accumulate(sq[m][h], nonfinite[m], h, "position", np.sqrt(e2), count_bad=False)
        if not segments:   # traces from one flight only
            segments += _segments(f.name, full, meas, preds, ok[H], t0, H, dt_s, n_segments)
    if sum(n_starts.values()) == 0:
        raise DataError("no start point of the rollout lies inside an in-flight interval with every "
                        "signal the models read (see the notes of droneid dataset)")
    rmse = {m: {h: {k: (math.sqrt(s / n) if n else math.nan) for k, (s, n) in sq[m][h].items()}
                for h in hs} for m in names}
    notes.append("state: " + "; ".join(f"{m}: {', '.join(axes[m])}" for m in names)
                 + "; every other signal taken from the log")
    states = None if keep_states is None else {
        h: {k: np.concatenate([part[k] for part in parts]) for k in parts[0]} for h, parts in kept.items() if parts}
    return RolloutResult(hs, float(dt_s), axes, pos_axes, rmse, n_starts, skipped, nonfinite,
                         tuple(segments), tuple(notes), states)


def _states(flight: str, t0, h: int, dt: float, ok, predicted, logged) -> dict[str, np.ndarray]:
    """The simulated state ``h`` steps after each start valid for ``h`` (see ``keep_states`` of
    :func:`rollout_errors`), as columns."""
    out = {"flight": np.full(int(ok.sum()), flight, dtype=object), "t0_s": t0[ok], "t_s": t0[ok] + h * dt}
    for k, arr in predicted.items():
        out[k] = arr[ok, h]
        out[f"{k}_logged"] = logged[k][ok, h]
    return out


def _accumulate(acc: dict, bad: dict, h: int, key: str, err: np.ndarray, count_bad: bool) -> None:
    fin = np.isfinite(err)
    if count_bad:
        bad[h] += int((~fin).sum())
    s, n = acc.get(key, (0.0, 0))
    acc[key] = (s + float(np.sum(err[fin] ** 2)), n + int(fin.sum()))


def _integrate(per: Mapping[str, IdentifiedModel], meas, pos, inputs, dt: float, H: int):
    """RK4 over all starts at once: velocities of the modelled axes (state) and their positions."""
    axes = [a for a in AXES if AXES[a][0] in per]
    fns = {a: (per[AXES[a][0]], compile_expression(per[AXES[a][0]].expr, per[AXES[a][0]].signals))
           for a in axes}

    def rhs(v, i):
        out = {}
        for a, (m, fn) in fns.items():
            cols = {s: (v[s] if s in v else inputs[(s, float(m.delays_s.get(s, 0.0)))][:, i])
                    for s in m.signals}
            out[a] = np.broadcast_to(fn(cols) if cols else float(m.expr), v[axes[0]].shape)
        return out

    n = meas[axes[0]].shape[0]
    V = {a: np.empty((n, H + 1)) for a in axes}
    P = {AXES[a][1]: np.empty((n, H + 1)) for a in axes if AXES[a][1] in pos}
    v = {a: meas[a][:, 0].copy() for a in axes}
    p = {q: pos[q][:, 0].copy() for q in P}
    for a in axes:
        V[a][:, 0] = v[a]
    for q in P:
        P[q][:, 0] = p[q]
    # the state: the modelled velocities and their positions (ṗ = v along the same RK4 stages)
    of = {AXES[a][1]: a for a in axes if AXES[a][1] in p}

    def deriv(x, at, i):
        k = rhs({a: x[a] for a in axes}, i + at)     # the model sees the velocities, never the
        # integrated positions (a model's z is the logged height, as before the step)
        k.update({q: x[a] for q, a in of.items()})
        return k
    x = {**v, **p}
    with np.errstate(all="ignore"):
        for j in range(H):
            x = rk4_step(lambda y, at, i=2 * j: deriv(y, at, i), x, dt, stage=_dict_axpy, update=_dict_combine)
            for a in axes:
                V[a][:, j + 1] = x[a]
            for q in P:
                P[q][:, j + 1] = x[q]
    return V, P


def _dict_axpy(x: dict, h: float, k: dict) -> dict:
    return {n: x[n] + h * k[n] for n in x}


def _dict_combine(x: dict, h: float, k1: dict, k2: dict, k3: dict, k4: dict) -> dict:
    return {n: x[n] + h * (k1[n] + 2 * k2[n] + 2 * k3[n] + k4[n]) for n in x}


def _segments(flight: str, full, meas, preds, ok_H, t0, H: int, dt: float, k: int) -> list[RolloutSegment]:
    """Up to ``k`` back-to-back traces valid for the longest horizon, from a quarter into the flight."""
    out, last = [], -math.inf
    start = t0[0] + 0.25 * (t0[-1] - t0[0])
    for i in np.flatnonzero(ok_H & (t0 >= start)):
        if t0[i] < last + H * dt - 1e-9:
            continue
        last = t0[i]
        out.append(RolloutSegment(flight, full[i].copy(), {a: meas[a][i].copy() for a in meas},
                                  {m: {a: v[a][i].copy() for a in v} for m, v in preds.items()}))
        if len(out) == k:
            break
    return out


# -- for reports --------------------------------------------------------------------------------
def horizon_section(models: Mapping[str, IdentifiedModel], empirical: Mapping[str, IdentifiedModel] | None,
                    refit: Mapping[str, IdentifiedModel] | None, flights,
                    horizons: Sequence[int] = (1, 10, 50), dt_s: float | None = None) -> dict:
    """The multi-step prediction section of a report as data: :meth:`RolloutResult.to_dict` of the
    identified models ({target: IdentifiedModel}), the empirical model as given and its refit (either
    may be None) and the constant-velocity baseline on ``flights``. Render with :func:`droneid.report.rollout.horizon_figures`."""
    sets = {"identified": models}
    if empirical:
        sets["empirical"] = empirical
    if refit:
        sets["refit"] = refit
    return rollout_errors(sets, flights, horizons, dt_s).to_dict()

