"""Write a :class:`Flight` as a flat CSV that :func:`parsers.mocap_csv.read_flat_csv` reads back.

One header row: ``t`` (seconds), then every canonical signal of the flight under its canonical
name (``x`` .. ``battery_voltage``; ``thrust`` as ``thrust_N``, ``motor1..N``, ``rpm1..N``; the full list in docs/signals.md),
then ``is_armed`` / ``is_flying`` (0/1) when the flight has "armed" / "in_flight" segments. All
columns are on the time base of the first signal in canonical order; other signals are
interpolated (angles unwrapped), and NaN (an empty cell) where a signal has no sample span.
Values are droneid's convention (ENU, FLU, SI) with 9 significant digits.
"""
from __future__ import annotations

import os

import numpy as np

from droneid.logs.flight import is_canonical
from droneid.core.io_util import atomic_write_text

from ._writer_util import group, require_some

__all__ = ["write_flat_csv"]


def write_flat_csv(flight, path) -> str:
    """Write ``flight`` to ``path`` as a flat CSV (atomically); returns the path."""
    path = os.fspath(path)
    require_some(flight, path, "csv")
    ordered = [g["name"] for g in flight.summary()["signals"]]
    names = tuple(n for n in ordered if is_canonical(n))
    t, v = group(flight, names, required=(names[0],))
    cols = {"t": t}
    for n in names:
        s = flight[n]
        out = np.asarray(v[n], float).copy()
        out[(t < s.start_s) | (t > s.end_s)] = np.nan
        cols["thrust_N" if n == "thrust" else n] = out     # "thrust" alone may read as 0..1
    for label, col in (("armed", "is_armed"), ("in_flight", "is_flying")):
        if label in flight.segments:
            on = np.zeros(t.size, bool)
            for a, b in flight.segments[label]:
                on |= (t >= a) & (t < b)
            cols[col] = on.astype(float)
    header = ",".join(cols)
    arr = np.column_stack(list(cols.values()))
    lines = [header] + [",".join("" if not np.isfinite(x) else f"{x:.9g}" for x in row) for row in arr]
    atomic_write_text(path, "\n".join(lines) + "\n")
    return path
