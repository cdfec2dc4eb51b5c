"""From flights to regression data: :class:`DatasetBuilder` and train/test splits.

``DatasetBuilder(...).build(flights, target="vx_dot")`` picks the in-flight part of each flight,
resamples the signals on a uniform grid of period ``ts`` seconds, computes the derivative target
with a differentiator of :mod:`droneid.core.differentiation` and returns a :class:`droneid.dataset.data.Dataset`
whose notes say what was done.

Steps, per flight:

1. **Which part.** ``in_flight="auto"``: the log's ``in_flight`` segments (intersected with
   ``armed`` when both exist), else the ``armed`` segments, else the whole log; in every case
   ground contact is then removed by detection, ``ground_margin_s`` wider on both sides (a log's
   "flying" flag is set while the vehicle still sits on the ground spinning up, where the ground,
   not the thrust, holds it). Ground = near the lowest height AND (still OR at idle power) when
   the log climbs more than ``3 * min_height_m`` above its lowest point; without that height cue,
   still AND at idle power (from those of speed / throttle-thrust-motors the flight has); then
   everything from a crash on is
   dropped (a ``crash`` event, tilt above ``crash_tilt_deg`` held for ``crash_hold_s``, or
   specific force above ``crash_accel`` on two samples within 0.2 s), with ``crash_margin_s``
   before it. ``in_flight="all"`` keeps the whole log. ``time_windows`` (seconds in each flight's
   own time base) then restrict every flight. Gaps longer than ``max(max_gap_s, 5 periods)`` in a
   required signal split the data: nothing is interpolated or differenced across them.
2. **Resampling.** Linear interpolation at ``t0 + k·ts`` in each interval. Signals in rad
   (roll, pitch, yaw, any signal with unit "rad") are unwrapped before and wrapped to [-π, π)
   after, when the original was wrapped; quaternions are made sign-continuous, interpolated and
   renormalised; when roll/pitch/yaw are absent they are derived from the quaternion at the
   native rate first, so Euler angles and quaternions agree.
3. **Targets.** ``<s>_dot`` is the derivative of signal ``s`` (``vx_dot`` from ``vx``); when
   ``vx``/``vy``/``vz`` are absent they come from ``x``/``y``/``z`` (velocity inputs by one, the
   target by two differentiations, said in the notes). ``forward`` and ``central`` work on the
   grid (the paper: ``v̇[k] = (v[k+1] − v[k]) / Ts``, the last sample of each interval dropped);
   the smoothing ones (``savgol``, ``spline``) work at the signal's native rate (uniformly
   resampled, at most 10 samples per grid step) and the derivative is then sampled on the grid.
"""
from __future__ import annotations

import logging
import math
from contextlib import contextmanager
from contextvars import ContextVar
from collections.abc import Sequence

import numpy as np

from droneid.dataset.data import Dataset
from droneid.core.differentiation import DIFFERENTIATORS, get_differentiator
from droneid.errors import ConfigError, DataError, MissingSignalError, check_choice
from droneid.logs.flight import CANONICAL_SIGNALS, Flight, Signal, is_canonical
from droneid.core.frames import quat_to_euler
from droneid.logs.in_flight import (Interval, _Detect, _fmt_iv, _intersect, _is_angle, in_flight_intervals, subtract_intervals,
                        resample_signal, signal_gaps)
from droneid.logs.screening import screen_signal
from droneid.core.targets import TARGETS, state_of

__all__ = ["DatasetBuilder", "reuse_datasets", "subsample",
           "resample_signal", "in_flight_intervals", "with_euler_from_quaternion", "signal_gaps"]

log = logging.getLogger(__name__)

_POSITION_OF = {t.velocity: t.position for t in TARGETS.values()}   # a view of the target table
_QUAT = ("qw", "qx", "qy", "qz")
_EULER = ("roll", "pitch", "yaw")



def _uniform_grid(a: float, b: float, step: float) -> np.ndarray:
    """``a, a + step, ...`` up to ``b``; a last point within round-off above ``b`` is put at ``b``
    (so a span of 12.7999999999 s at 0.05 s keeps its 12.8 s sample inside the signal)."""
    grid = a + step * np.arange(int(math.floor((b - a) / step + 1e-9)) + 1)
    return np.minimum(grid, b)


def _resample_quaternion(flight: Flight, t: np.ndarray) -> dict[str, np.ndarray]:
    """qw..qz at ``t``: sign-continuous, interpolated per component on the qw stamps, renormalised."""
    ref = flight["qw"]
    q = np.column_stack([resample_signal(flight[n], ref.t) for n in _QUAT])
    # the same rotation may flip sign between samples: keep each close to the previous one
    flips = np.cumsum(np.concatenate([[0], (np.einsum("ij,ij->i", q[1:], q[:-1]) < 0)])) % 2
    q[flips == 1] *= -1
    out = np.column_stack([np.interp(t, ref.t, q[:, i], left=np.nan, right=np.nan) for i in range(4)])
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return {n: out[:, i] for i, n in enumerate(_QUAT)}


def with_euler_from_quaternion(flight: Flight) -> tuple[Flight, list[str]]:
    """(flight, notes): the flight with roll, pitch, yaw (rad, Z-Y-X) derived from its quaternion
    when it has a quaternion but no Euler angles; unchanged (and no notes) otherwise."""
    if flight.has(*_EULER) or not flight.has(*_QUAT):
        return flight, []
    ref = flight["qw"]
    q = np.column_stack([resample_signal(flight[n], ref.t) for n in _QUAT])
    ok = np.all(np.isfinite(q), axis=1)
    roll, pitch, yaw = quat_to_euler(q[ok])
    sigs = [Signal(n, ref.t[ok], v, "rad", "quaternion qw,qx,qy,qz") for n, v in
            zip(_EULER, (roll, pitch, yaw)) if not flight.has(n)]
    return (flight.with_signals(*sigs),
            [f"{', '.join(s.name for s in sigs)} derived from the attitude quaternion"])


# -- which part of a flight ---------------------------------------------------------------------
_D = _Detect()   # the detection defaults, one home

#: the datasets built inside :func:`reuse_datasets` (None outside): key -> (flights, Dataset)
_REUSE: ContextVar[dict | None] = ContextVar("droneid_reused_datasets", default=None)


def _reused(what: tuple, obj, compute):
    """``compute()`` for ``obj`` (a Flight or Signal: immutable), once per :func:`reuse_datasets`
    block (no caching outside one)."""
    cache = _REUSE.get()
    if cache is None:
        return compute()
    key = (*what, id(obj))
    hit = cache.get(key)
    if hit is None or hit[0] is not obj:
        hit = cache[key] = (obj, compute())
    return hit[1]


@contextmanager
def reuse_datasets():
    """A block in which :meth:`DatasetBuilder.build` builds each dataset once: the same flights
    (the same objects), builder settings, target, inputs and extras give the same frozen
    :class:`~droneid.dataset.data.Dataset`. identify runs its stages in one, so the offset search, the
    hover calibration, the diagnosis, the problem and the ladder share their datasets. A block
    inside another one shares the outer block's datasets."""
    token = _REUSE.set({}) if _REUSE.get() is None else None
    try:
        yield
    finally:
        if token is not None:
            _REUSE.reset(token)




class DatasetBuilder:
    """Builds regression datasets from flights (see the module docstring for the steps).

    Parameters (stored as given; checked by :meth:`build`)
    ----------
    ts : grid period in seconds (paper: 0.05)
    method : differentiator name, one of :data:`droneid.core.differentiation.DIFFERENTIATORS`
    window_s : smoothing window in seconds for ``savgol`` (default 0.25) and ``spline``
        (default: chosen by cross-validation); must be None for ``forward`` and ``central``
    in_flight : ``"auto"`` (segments / detection / crash trim) or ``"all"`` (whole logs)
    time_windows : sequence of ``(start_s, end_s)`` kept in every flight (its own time base)
    max_gap_s : a longer gap (or 5 sample periods, whichever is longer) in a required signal
        splits the data
    min_height_m, still_speed, idle_fraction, min_segment_s : ground detection thresholds (m above
        the lowest height, m/s, fraction of the 90th-percentile power, shortest airborne run in s)
    crash_tilt_deg, crash_hold_s, crash_accel, crash_margin_s : crash detection
    ground_margin_s : ground contact is trimmed this much (s) longer on both sides (lift-off and
        touchdown, where the ground still pushes); contact is trimmed even where the log declares
        in-flight segments (a "flying" flag is set while the vehicle still sits on the ground)
    delays_s : {signal: delay in s}: that input (or extra) is read at ``t − delay`` (an input whose
        effect lags its logged value, e.g. motor speeds logged ahead of the thrust they make; a
        negative delay reads a stream whose stamps are late at its true time);
        samples whose delayed time falls before the signal starts are dropped
    """

    def __init__(self, ts=0.05, method="forward", window_s=None, in_flight="auto",
                 time_windows=None, *, max_gap_s=0.5, min_height_m=_D.min_height_m, still_speed=_D.still_speed,
                 idle_fraction=_D.idle_fraction, min_segment_s=_D.min_segment_s, crash_tilt_deg=_D.crash_tilt_deg,
                 crash_hold_s=_D.crash_hold_s, crash_accel=_D.crash_accel, crash_margin_s=_D.crash_margin_s,
                 ground_margin_s=_D.ground_margin_s, delays_s=None):
        self.ts = ts
        self.delays_s = delays_s
        self.method = method
        self.window_s = window_s
        self.in_flight = in_flight
        self.time_windows = time_windows
        self.max_gap_s = max_gap_s
        self.min_height_m = min_height_m
        self.still_speed = still_speed
        self.idle_fraction = idle_fraction
        self.min_segment_s = min_segment_s
        self.crash_tilt_deg = crash_tilt_deg
        self.crash_hold_s = crash_hold_s
        self.crash_accel = crash_accel
        self.crash_margin_s = crash_margin_s
        self.ground_margin_s = ground_margin_s

    def _detect(self) -> _Detect:
        return _Detect(self.min_height_m, self.still_speed, self.idle_fraction, self.min_segment_s,
                       self.crash_tilt_deg, self.crash_hold_s, self.crash_accel, self.crash_margin_s,
                       self.ground_margin_s)

    # -- validation --
    def _validate(self):
        for name in ("ts", "max_gap_s", "min_height_m", "still_speed", "idle_fraction",
                     "min_segment_s", "crash_tilt_deg", "crash_hold_s", "crash_accel",
                     "crash_margin_s", "ground_margin_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 \
                    or (name == "ts" and v == 0):
                raise ConfigError(f"The '{name}' parameter of DatasetBuilder must be a "
                                  f"{'positive' if name == 'ts' else 'non-negative'} number. "
                                  f"Got {v!r} instead.")
        check_choice("method", self.method, DIFFERENTIATORS, owner="DatasetBuilder")
        for name, d in dict(self.delays_s or {}).items():
            if isinstance(d, bool) or not isinstance(d, (int, float)) or not math.isfinite(d) or not -5 <= d <= 5:
                raise ConfigError(f"The delay of '{name}' (DatasetBuilder delays_s) must be a number of "
                                  f"seconds in [-5, 5]. Got {d!r} instead.")
        check_choice("in_flight", self.in_flight, ("auto", "all"), owner="DatasetBuilder")
        if self.window_s is not None and self.method in ("forward", "central"):
            raise ConfigError(f"The 'window_s' parameter of DatasetBuilder applies to the smoothing "
                              f"methods (savgol, spline), not to {self.method!r}. Got {self.window_s!r}.")
        params = {} if self.window_s is None else {"window_s": self.window_s}
        diff = get_differentiator(self.method, **params)
        windows = None
        if self.time_windows is not None:
            windows = []
            for w in self.time_windows:
                try:
                    a, b = (float(x) for x in w)
                except (TypeError, ValueError):
                    raise ConfigError(f"a time window must be a (start_s, end_s) pair. Got {w!r}.") from None
                if not (a < b) or math.isnan(a) or math.isnan(b):
                    raise ConfigError(f"time window {w!r} is empty or not finite: start must be < end")
                windows.append((a, b))
        return diff, windows

    # -- build --
    def build(self, flights, target: str = "vx_dot", inputs=None, extras=None) -> Dataset:
        """The dataset for ``target`` from one flight or a sequence of flights.

        ``inputs``: signal names (default: the target's ``paper_inputs`` in
        :data:`droneid.core.targets.TARGETS`). ``extras``: further signals resampled on the same grid
        into ``Dataset.extra`` (default: every canonical signal all flights have; ``()`` for
        none). Raises MissingSignalError, ConfigError or DataError. Inside
        :func:`reuse_datasets`, the same request on the same flights is built once.
        """
        cache = _REUSE.get()
        if cache is None:
            return self._build(flights, target, inputs, extras)
        group = [flights] if isinstance(flights, Flight) else list(flights)
        settings = {**vars(self), "delays_s": {k: v for k, v in (self.delays_s or {}).items() if v}}
        key = (tuple(map(id, group)), repr(target), repr(None if inputs is None else tuple(inputs)),
               repr(None if extras is None else tuple(extras)), repr(sorted(settings.items())))
        hit = cache.get(key)
        if hit is None or any(a is not b for a, b in zip(hit[0], group)):
            hit = cache[key] = (group, self._build(flights, target, inputs, extras))
        return hit[1]

    def _build(self, flights, target, inputs, extras) -> Dataset:
        diff, windows = self._validate()
        if isinstance(flights, Flight):
            flights = [flights]
        flights = list(flights)
        if not flights or not all(isinstance(f, Flight) for f in flights):
            raise ConfigError("build() needs a Flight or a non-empty sequence of Flights")
        if not isinstance(target, str) or not target.endswith("_dot") or len(target) <= 4:
            raise ConfigError(f"The 'target' parameter must name a derivative such as 'vx_dot'. "
                              f"Got {target!r} instead.")
        source = state_of(target)
        prepared, prep_notes = [], []
        for f in flights:
            g, n = with_euler_from_quaternion(f)
            prepared.append(g)
            prep_notes.append(n)

        def available(f: Flight, name: str) -> bool:
            return f.has(name) or (name in _POSITION_OF and f.has(_POSITION_OF[name])) \
                or (name in _QUAT and f.has(*_QUAT))

        if inputs is None:
            if target not in TARGETS:
                raise ConfigError(f"no default inputs for target {target!r}: pass inputs "
                                  f"(defaults exist for {', '.join(TARGETS)})")
            inputs = [n for n in TARGETS[target].paper_inputs
                      if n != "throttle" or all(f.has("throttle") for f in prepared)]
        elif isinstance(inputs, str):
            inputs = [s.strip() for s in inputs.split(",") if s.strip()]
        inputs = list(dict.fromkeys(inputs))
        if not inputs:
            raise ConfigError("no inputs given")
        if target in inputs:
            raise ConfigError(f"the target {target!r} cannot also be an input")
        explicit_extras = extras is not None
        if extras is None:
            names = set()
            for f in prepared:
                names |= {n for n in f.names if is_canonical(n)} | \
                    {v for v, p in _POSITION_OF.items() if f.has(p)}
            extras = [n for n in (*CANONICAL_SIGNALS, *(f"motor{i}" for i in range(1, 17)),
                                  *(f"rpm{i}" for i in range(1, 17)))
                      if n in names and n not in inputs]
        elif isinstance(extras, str):
            extras = [s.strip() for s in extras.split(",") if s.strip()]
        extras = [n for n in dict.fromkeys(extras) if n not in inputs and n != target]

        for f in prepared:
            where = f"flight '{f.name}'" + (f" ({f.provenance.files[0]})" if f.provenance.files else "")
            for n in [*inputs, *(extras if explicit_extras else ())]:
                if not available(f, n):
                    raise MissingSignalError(n, f.names, where=where)
            if not available(f, source):
                raise MissingSignalError(source, f.names, where=f"{where} (needed for {target})")

        sources = _unique_names([f.name for f in flights])
        notes = [f"grid period ts = {self.ts:g} s; target {target} by {diff!r}"]
        parts = []
        screened: dict[str, int] = {}
        for k, f in enumerate(prepared):
            cols, y, t, fnotes, fscreened = self._build_one(f, diff, windows, source, inputs, extras,
                                                            explicit_extras)
            for n, c in fscreened.items():
                screened[n] = screened.get(n, 0) + c
            notes.extend(f"{sources[k]}: {n}" for n in
                         [*(f"log: {n}" for n in f.provenance.notes), *prep_notes[k], *fnotes])
            parts.append((k, cols, y, t))
        n_total = sum(p[2].size for p in parts)
        if n_total == 0:
            raise DataError(f"no samples left for {target}: " + "; ".join(notes[1:]))
        # extras must exist for every sample: drop incomplete automatic ones
        keep_extras = []
        for n in extras:
            vals = [p[1].get(n) for p in parts if p[2].size]
            if all(v is not None and np.all(np.isfinite(v)) for v in vals):
                keep_extras.append(n)
            elif explicit_extras:
                keep_extras.append(n)
                notes.append(f"extra '{n}' is nan where the signal has no data")
            else:
                notes.append(f"extra '{n}' left out: not available over the whole grid of every flight")
        X = np.vstack([np.column_stack([p[1][n] for n in inputs]) for p in parts if p[2].size])
        y = np.concatenate([p[2] for p in parts if p[2].size])
        t = np.concatenate([p[3] for p in parts if p[3].size])
        fl = np.concatenate([np.full(p[2].size, p[0]) for p in parts if p[2].size])
        extra = {n: np.concatenate([p[1][n] for p in parts if p[2].size]) for n in keep_extras}
        notes.append(f"{y.size} samples from {len(flights)} flight(s)")
        return Dataset(X, y, t, tuple(inputs), target, fl, tuple(sources), extra, tuple(notes), screened)

    def _build_one(self, f: Flight, diff, windows, source, inputs, extras, explicit_extras):
        notes: list[str] = []
        ts = float(self.ts)
        if self.in_flight == "auto":
            ivs, n = _reused(("in_flight", ts, self._detect()), f,
                             lambda: in_flight_intervals(f, ts=ts, detect=self._detect()))
            notes.extend(n)
        else:
            ivs = [(f.start_s, f.end_s)]
        if windows is not None:
            ivs = _intersect(ivs, windows)
            notes.append(f"time windows applied: {_fmt_iv(ivs)}")
        # required signals: their common span, minus their gaps
        need = {}
        derived = []
        for n in [source, *inputs, *(extras if explicit_extras else ())]:
            if f.has(n):
                need[n] = f[n]
            elif n in _POSITION_OF and f.has(_POSITION_OF[n]):
                need[_POSITION_OF[n]] = f[_POSITION_OF[n]]
                derived.append(n)
            elif n in _QUAT:
                for q in _QUAT:
                    need[q] = f[q]
        delays = dict(self.delays_s or {})
        screened: dict[str, int] = {}
        holes: list[Interval] = []
        for n, sig in need.items():
            d = float(delays.get(n, 0.0))      # a delayed input is read at t - d: its gaps and holes move by d
            ivs = subtract_intervals(_intersect(ivs, [(sig.start_s, sig.end_s)]),
                            [(a + d, b + d) for a, b in _reused(("gaps", self.max_gap_s), sig,
                                                                lambda: signal_gaps(sig, self.max_gap_s))])
            sc = _reused(("screen",), sig, lambda: screen_signal(sig))   # implausible samples: holes no row may use
            if sc.implausible:
                if diff.name == "spline" and n in (source, _POSITION_OF.get(source)):
                    ivs = subtract_intervals(ivs, sc.holes)   # a spline smooths the whole interval
                holes += [(a + d, b + d) for a, b in sc.holes]
                screened[n] = sc.implausible
                notes.append(f"screened {sc.describe()}: rows that use them are left out")
            if len(sig) > 1 and _reused(("rate",), sig, lambda: sig.rate_hz) < 1.0 / ts * 0.999:
                notes.append(f"signal '{n}' is sampled at {sig.rate_hz:.3g} Hz, below the grid rate "
                             f"{1 / ts:.3g} Hz: interpolated")
        # a row depends on the samples within its differentiator's stencil (±h): it is left out when
        # that reaches a hole; the grid and every other row stay as they are
        h = float(getattr(diff, "window_s", None) or 0.0) / 2 if diff.smoothing else 0.0
        order = 1 if f.has(source) else 2          # a target from positions: differentiated twice
        h = order * max(h, ts) + 1e-9
        for n in dict.fromkeys(derived):
            what = "the target" if n == source else "input"
            notes.append(f"{n} ({what}) derived from {_POSITION_OF[n]} by {diff.name} differences"
                         + (" (target: differentiated twice)" if n == source else ""))
        cols_parts, y_parts, t_parts = [], [], []
        n_dropped = n_short = 0
        n_screened_rows = 0
        for a, b in ivs:
            grid = _uniform_grid(a, b, ts)
            if grid.size < max(3, diff.min_samples):
                n_short += 1
                continue
            cols = {}
            for n in dict.fromkeys([*inputs, *extras]):
                cols[n] = self._column(f, n, grid, diff, a, b)
            y = self._derivative(f, source, grid, diff, a, b)
            ok = np.isfinite(y)
            for n in inputs:
                ok &= np.isfinite(cols[n])
            n_dropped += int((~ok).sum())
            if holes:
                hit = np.zeros(grid.size, dtype=bool)
                for h0, h1 in holes:
                    hit |= (grid + h > h0) & (grid - h < h1)
                n_screened_rows += int((hit & ok).sum())
                ok &= ~hit
            cols_parts.append({k: (v[ok] if v is not None else None) for k, v in cols.items()})
            y_parts.append(y[ok])
            t_parts.append(grid[ok])
        if n_screened_rows:
            notes.append(f"{n_screened_rows} grid sample(s) left out: their inputs or the target's "
                         f"differences reach a screened sample")
        if n_short:
            notes.append(f"{n_short} interval(s) shorter than the differentiator needs were skipped")
        if n_dropped:
            notes.append(f"{n_dropped} grid sample(s) without a finite target or input dropped "
                         + ("(the forward difference has none at the end of each interval)"
                            if diff.name == "forward" else ""))
        used = [(float(tp[0]), float(tp[-1])) for tp in t_parts if tp.size]
        notes.append(f"used {_fmt_iv(used)}")
        if not y_parts:
            return {}, np.empty(0), np.empty(0), notes, screened
        cols = {}
        for n in dict.fromkeys([*inputs, *extras]):
            vals = [c[n] for c in cols_parts]
            cols[n] = None if any(v is None for v in vals) else np.concatenate(vals)
        return cols, np.concatenate(y_parts), np.concatenate(t_parts), notes, screened

    def _column(self, f: Flight, name: str, grid, diff, a, b):
        delay = float(dict(self.delays_s or {}).get(name, 0.0))
        if delay and f.has(name):
            return resample_signal(f[name], grid - delay)
        if f.has(name):
            return resample_signal(f[name], grid)
        if name in _QUAT and f.has(*_QUAT):
            return _resample_quaternion(f, grid)[name]
        if name in _POSITION_OF and f.has(_POSITION_OF[name]):
            return self._differentiate(f[_POSITION_OF[name]], grid, diff, a, b, order=1)
        return None

    def _derivative(self, f: Flight, source: str, grid, diff, a, b):
        if f.has(source):
            return self._differentiate(f[source], grid, diff, a, b, order=1)
        return self._differentiate(f[_POSITION_OF[source]], grid, diff, a, b, order=2)

    @staticmethod
    def _differentiate(sig: Signal, grid, diff, a, b, order: int):
        angle = _is_angle(sig)
        if diff.smoothing:
            # at the native rate (uniform; at most 10 steps per grid step), then on the grid
            ts = float(grid[1] - grid[0])
            native = float(np.median(np.diff(sig.t))) if len(sig) > 1 else ts
            h = min(max(native, ts / 10), ts)
            fine = _uniform_grid(a, b, h)
            v = _unwrapped(sig, fine) if angle else resample_signal(sig, fine)
            for _ in range(order):
                v = diff(v, fine)
            return np.interp(grid, fine, v)
        v = _unwrapped(sig, grid) if angle else resample_signal(sig, grid)
        for _ in range(order):
            v = diff(v, grid)
            if order > 1 and not np.all(np.isfinite(v)):
                # forward differences: keep the finite prefix for the next pass
                k = int(np.argmin(np.isfinite(v)))
                nxt = np.full_like(v, np.nan)
                if k >= 2:
                    nxt[:k] = diff(v[:k], grid[:k])
                return nxt
        return v


def _unwrapped(sig: Signal, t) -> np.ndarray:
    return np.interp(t, sig.t, np.unwrap(sig.values), left=np.nan, right=np.nan)


def _unique_names(names: Sequence[str]) -> list[str]:
    out, seen = [], {}
    for n in names:
        if names.count(n) > 1:
            seen[n] = seen.get(n, 0) + 1
            out.append(f"{n}#{seen[n]}")
        else:
            out.append(n)
    return out


# -- splits -------------------------------------------------------------------------------------
def subsample(ds: Dataset, n: int, seed=0) -> Dataset:
    """``n`` samples drawn without replacement (kept in their original order); the whole
    dataset when it has ``n`` or fewer."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ConfigError(f"The 'n' parameter of subsample must be a positive integer. Got {n!r} instead.")
    if n >= len(ds):
        return ds
    idx = np.sort(np.random.default_rng(seed).choice(len(ds), size=int(n), replace=False))
    return ds.subset(idx).noted(f"subsampled to {n} of {len(ds)} samples (seed {seed})")
