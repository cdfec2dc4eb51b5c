"""Time alignment of two recordings of one flight (e.g. mocap CSV + autopilot log).

:func:`estimate_clock_offset` finds the offset between the two clocks by cross-correlating a
signal both recordings have (speed, vertical velocity, yaw rate, height, or any named signal),
with parabolic sub-sample refinement of the correlation peak. :func:`merge_flights` shifts the
secondary recording onto the primary's clock and joins their signals (the primary's win on
name clashes).

Convention: ``offset_s`` is what must be ADDED to the secondary's time stamps to put them on the
primary's clock: ``merge_flights`` uses ``secondary.shifted(offset_s)``.
"""
from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from droneid.dataset.builder import with_euler_from_quaternion
from droneid.errors import ConfigError, DataError, MissingSignalError
from droneid.logs.flight import Diagnostics, Flight, Provenance

__all__ = ["estimate_clock_offset", "merge_flights", "ALIGN_SIGNALS"]

log = logging.getLogger(__name__)

#: derived alignment signals tried in this order by ``signal="auto"``
ALIGN_SIGNALS = ("speed", "vz", "yaw_rate", "z")


def _series(f: Flight, name: str):
    """(t, values) of an alignment signal at native stamps, or None if the flight lacks it."""
    if name == "speed":
        if f.has("vx", "vy", "vz"):
            t = f["vx"].t
            v = [np.interp(t, f[n].t, f[n].values) for n in ("vx", "vy", "vz")]
            return t, np.sqrt(sum(c * c for c in v))
        if f.has("x", "y", "z") and len(f["x"]) > 2:
            t = f["x"].t
            v = [np.gradient(np.interp(t, f[n].t, f[n].values), t) for n in ("x", "y", "z")]
            return t, np.sqrt(sum(c * c for c in v))
        return None
    if name == "vz":
        if f.has("vz"):
            return f["vz"].t, f["vz"].values
        if f.has("z") and len(f["z"]) > 2:
            return f["z"].t, np.gradient(f["z"].values, f["z"].t)
        return None
    if name == "yaw_rate":
        if not f.has("yaw"):
            f = with_euler_from_quaternion(f)[0]
        if f.has("yaw") and len(f["yaw"]) > 2:
            return f["yaw"].t, np.gradient(np.unwrap(f["yaw"].values), f["yaw"].t)
        return None
    if f.has(name):
        s = f[name]
        return s.t, (np.unwrap(s.values) if s.unit == "rad" else s.values)
    return None


def estimate_clock_offset(a: Flight, b: Flight, signal: str = "auto",
                          max_offset_s: float | None = None, dt_s: float | None = None,
                          smooth_s: float = 0.2) -> float:
    """Seconds to add to ``b``'s time stamps to put them on ``a``'s clock.

    ``signal``: ``"auto"`` (the first of :data:`ALIGN_SIGNALS` both flights provide and that
    varies), a derived one (``speed``, ``vz``, ``yaw_rate``: from velocities or positions, yaw or
    quaternion) or any signal name. ``max_offset_s`` bounds the search (default: lags with at least
    half of the shorter recording overlapping). ``dt_s``: correlation grid step (default: the
    finer of the two signals' periods). ``smooth_s``: both series are smoothed by the same
    centred (zero-delay) Savitzky-Golay filter over this many seconds before correlating, which
    tames the noise of velocities derived from positions (0 for none). The peak is refined to a fraction of ``dt_s`` by a
    parabola through the three best lags. Raises DataError when no usable common signal exists.
    """
    if signal == "auto":
        for name in ALIGN_SIGNALS:
            sa, sb = _series(a, name), _series(b, name)
            if sa is not None and sb is not None and np.nanstd(sa[1]) > 1e-6 and np.nanstd(sb[1]) > 1e-6:
                signal = name
                break
        else:
            raise DataError("no common signal to align the two recordings on (tried "
                            f"{', '.join(ALIGN_SIGNALS)}); pass signal= or offset_s=")
        log.debug("aligning on %s", signal)
    sa, sb = _series(a, signal), _series(b, signal)
    for f, s in ((a, sa), (b, sb)):
        if s is None:
            raise MissingSignalError(signal, [*f.names, *ALIGN_SIGNALS],
                                     where=f"flight '{f.name}' (clock alignment)")
    (ta, va), (tb, vb) = sa, sb
    if ta.size < 4 or tb.size < 4:
        raise DataError(f"too few samples of '{signal}' to align ({ta.size} and {tb.size})")
    if dt_s is None:
        dt_s = float(min(np.median(np.diff(ta)), np.median(np.diff(tb))))
    if not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s) and dt_s > 0):
        raise ConfigError(f"The 'dt_s' parameter must be a positive number. Got {dt_s!r} instead.")
    ga = ta[0] + dt_s * np.arange(int((ta[-1] - ta[0]) / dt_s) + 1)
    gb = tb[0] + dt_s * np.arange(int((tb[-1] - tb[0]) / dt_s) + 1)
    xa = _normalise(_smooth(np.interp(ga, ta, va), smooth_s, dt_s))
    xb = _normalise(_smooth(np.interp(gb, tb, vb), smooth_s, dt_s))
    if xa is None or xb is None:
        raise DataError(f"'{signal}' does not vary in one of the recordings: cannot align on it")
    score, offsets = _pearson_by_lag(xa, xb)
    offsets = ga[0] - gb[0] + offsets * dt_s
    if max_offset_s is not None:
        score = np.where(np.abs(offsets) <= max_offset_s, score, -np.inf)
    if not np.isfinite(score).any():
        raise DataError("the recordings do not overlap enough for any allowed offset")
    k = int(np.argmax(score))
    frac = 0.0
    if 0 < k < score.size - 1 and np.isfinite(score[k - 1]) and np.isfinite(score[k + 1]):
        y0, y1, y2 = score[k - 1], score[k], score[k + 1]
        den = y0 - 2 * y1 + y2
        if den < 0:
            frac = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5))
    return float(offsets[k] + frac * dt_s)


def _pearson_by_lag(xa: np.ndarray, xb: np.ndarray):
    """Pearson correlation of ``xa[n + k]`` with ``xb[n]`` over their overlap, for every lag k
    whose overlap holds at least half of the shorter series (-inf elsewhere); and the lags."""
    from scipy.signal import correlate, correlation_lags
    na, nb = xa.size, xb.size
    sab = correlate(xa, xb, mode="full", method="fft")
    lags = correlation_lags(na, nb, mode="full")
    ca = np.concatenate([[0.0], np.cumsum(xa)])
    ca2 = np.concatenate([[0.0], np.cumsum(xa * xa)])
    cb = np.concatenate([[0.0], np.cumsum(xb)])
    cb2 = np.concatenate([[0.0], np.cumsum(xb * xb)])
    a0, a1 = np.maximum(lags, 0), np.minimum(na, nb + lags)
    b0, b1 = np.maximum(-lags, 0), np.minimum(nb, na - lags)
    n = (a1 - a0).astype(float)
    ok = n >= 0.5 * min(na, nb)
    n = np.maximum(n, 1.0)
    sa, sa2 = ca[a1] - ca[a0], ca2[a1] - ca2[a0]
    sb, sb2 = cb[b1] - cb[b0], cb2[b1] - cb2[b0]
    cov = sab - sa * sb / n
    var = np.maximum(sa2 - sa * sa / n, 0.0) * np.maximum(sb2 - sb * sb / n, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = cov / np.sqrt(var)
    return np.where(ok & np.isfinite(r), r, -np.inf), lags


def _smooth(x: np.ndarray, smooth_s: float, dt_s: float) -> np.ndarray:
    n = int(round(smooth_s / dt_s)) | 1
    if smooth_s <= 0 or n < 5 or n > x.size:
        return x
    from scipy.signal import savgol_filter
    return savgol_filter(x, n, 2, mode="interp")


def _normalise(x: np.ndarray):
    s = float(np.std(x))
    if not math.isfinite(s) or s <= 1e-12:
        return None
    return (x - np.mean(x)) / s


def merge_flights(primary: Flight, secondary: Flight, offset_s: float | None = None,
                  signal: str = "auto") -> Flight:
    """One flight from two recordings: ``secondary`` shifted by ``offset_s`` (estimated with
    :func:`estimate_clock_offset` when None) and joined to ``primary``. Signals both have keep
    the primary's samples (listed in the notes); segments come from the primary, or from the
    secondary (shifted) when the primary has none; events are joined."""
    if offset_s is None:
        offset_s = estimate_clock_offset(primary, secondary, signal=signal)
        how = f"estimated from {signal}"
    else:
        if isinstance(offset_s, bool) or not isinstance(offset_s, (int, float)) or not math.isfinite(offset_s):
            raise ConfigError(f"The 'offset_s' parameter must be a finite number. Got {offset_s!r} instead.")
        how = "given"
    sec = secondary.shifted(float(offset_s))
    sig = dict(primary.signals)
    clashes = [n for n in sec.signals if n in sig]
    for n, s in sec.signals.items():
        sig.setdefault(n, s)
    segments = dict(primary.segments) or dict(sec.segments)
    notes = [*primary.provenance.notes, *(f"{secondary.name}: {n}" for n in secondary.provenance.notes),
             f"merged {secondary.name} into {primary.name} with clock offset {offset_s:+.4f} s ({how})"]
    if clashes:
        notes.append(f"signals in both, kept from {primary.name}: {', '.join(sorted(clashes))}")
    prov = Provenance(files=primary.provenance.files + secondary.provenance.files,
                      format=f"{primary.provenance.format}+{secondary.provenance.format}",
                      vehicle=primary.provenance.vehicle or secondary.provenance.vehicle,
                      firmware=primary.provenance.firmware or secondary.provenance.firmware,
                      notes=tuple(notes))
    diag = Diagnostics(primary.diagnostics.skipped, primary.diagnostics.warnings) \
        .add(secondary.diagnostics.skipped, secondary.diagnostics.warnings)
    return replace(primary, signals=sig, provenance=prov, diagnostics=diag, segments=segments,
                   events=primary.events + sec.events)
