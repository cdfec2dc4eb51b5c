"""The DataFlash record container, read with pymavlink's ``DFReader``: ONE home for what the
ArduPilot ``.bin`` reader (:mod:`parsers.dataflash_log`) and the PX4 sdlog2 ``.px4log`` reader
(:mod:`parsers.px4log`) share. Both write the same records (0xA3 0x95, a type byte, packed
fields described by FMT records); they differ in the messages and in how time is stamped.

:func:`scan` streams the wanted message types once and returns, per type, a time column and the
wanted fields as Python lists (:class:`TypeRows`). A reader says how its messages are stamped
with a ``clock(mtype, columns) -> (field, seconds per unit) | None``; records of an untimed type
take the time of the previous timed record. Damage is skipped and counted into the
:class:`~parsers._build.FlightBuilder`: a damaged FMT (a type without its needed fields), bytes
no record covers (pymavlink resynchronised), a record cut by the end of the file, a record
pymavlink cannot decode (reading stops there, what came before is kept).
"""
from __future__ import annotations

import gc
import math
import warnings
from collections.abc import Callable, Mapping
from operator import attrgetter

import numpy as np

from droneid.errors import LogFormatError

from ._build import FlightBuilder

__all__ = ["scan", "TypeRows", "columns", "timed_columns", "instance0", "Clock"]

#: ``clock(mtype, columns)``: the field stamping a message type and its seconds per unit, or
#: None for a type without a time of its own
Clock = Callable[[str, list], "tuple[str, float] | None"]


def _open(path, kind: str):
    from pymavlink import DFReader  # wrapped here: pymavlink reads globals at import
    # a reader that fails half-built leaves its file open; it is closed here, when the reader is
    # collected, instead of a ResourceWarning reaching the user later from the garbage collector
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        try:
            return DFReader.DFReader_binary(path, zero_time_base=True)
        except Exception as exc:  # pymavlink raises bare exceptions on broken headers
            why = f"{type(exc).__name__}: {exc}"
        gc.collect()
    raise LogFormatError(path, f"not a readable {kind} ({why})")


class TypeRows:
    """Rows of one message type: a time column (seconds of the log's clock) and the wanted
    fields, as Python lists."""
    __slots__ = ("time_field", "scale", "fields", "get", "rows", "times")

    def __init__(self, fields: tuple[str, ...], stamp: "tuple[str, float] | None"):
        self.time_field, self.scale = stamp if stamp else (None, 1.0)
        self.fields = fields
        if len(self.fields) > 1:
            self.get = attrgetter(*self.fields)           # returns a tuple
        else:
            one = attrgetter(*self.fields) if self.fields else (lambda m: None)
            self.get = lambda m: (one(m),)
        self.rows: list = []
        self.times: list = []


def scan(path, b: FlightBuilder, want: Mapping[str, tuple[str, ...]],
         required: Mapping[str, tuple[str, ...]], clock: Clock, kind: str) -> dict[str, TypeRows]:
    """One pass over the log: {type: :class:`TypeRows`} of the types in ``want`` (type -> the
    fields wanted; those a log lacks are ignored) whose FMT has the ``required`` fields.

    pymavlink prints one line per damaged byte; read_flight captures that output. The damage is
    counted here from pymavlink's own index instead: the bytes no indexed record covers.
    ``kind`` names the format in errors ("DataFlash log")."""
    dflog = _open(path, kind)
    try:
        types = _loop(dflog, b, want, required, clock)
        _check_end(dflog, b)
        _count_damage(dflog, b)
    finally:                    # pymavlink leaves its file and map open (a ResourceWarning)
        # each closed on its own: DFReader.close() stops at the map when a view of it is still
        # alive (BufferError) and never reaches the file, which the garbage collector then
        # reported as an unclosed file in a later test
        for part in (getattr(dflog, "data_map", None), getattr(dflog, "filehandle", None)):
            try:
                if part is not None:
                    part.close()
            except (OSError, ValueError, BufferError):
                pass
    return types


def _count_damage(dflog, b: FlightBuilder) -> None:
    """Bytes before the last record that no record pymavlink indexed covers (garbage, damaged
    headers); what follows the last record is :func:`_check_end`'s."""
    try:
        size = int(dflog.data_len)
        covered, last_end = 0, 0
        for mtype, offs in enumerate(dflog.offsets):
            if offs and mtype in dflog.formats:
                o = np.asarray(offs, dtype=np.int64)
                ln = dflog.formats[mtype].len
                covered += int(np.minimum(ln, size - o).sum())
                last_end = max(last_end, int(o[-1]) + ln)
    except (AttributeError, TypeError, ValueError, IndexError):
        return
    gap = min(size, last_end) - covered
    if gap > 0:
        b.skip("corrupt bytes outside any record (pymavlink resynchronised)", gap)


def _loop(dflog, b: FlightBuilder, want, required, clock) -> dict:
    """The streaming loop: only the wanted types, fields pulled into lists per type."""
    types: dict[str, TypeRows | None] = {}
    last = math.nan
    recv = dflog.recv_match
    wanted = list(want)
    broken: dict[str, list[str]] = {}
    n_bad = 0
    while True:
        try:
            m = recv(type=wanted)
        except Exception as exc:  # a cut or corrupt record: keep what came before
            n_bad += 1
            b.warn(f"reading stopped at a corrupt record ({type(exc).__name__}: {exc})")
            break
        if m is None:
            break
        mtype = m.get_type()
        tr = types.get(mtype)
        if tr is None and mtype not in types:
            cols = list(m.get_fieldnames())
            lost = [f for f in required.get(mtype, ()) if f not in cols]
            if lost:
                tr = types[mtype] = None
                broken[mtype] = lost
            else:
                tr = types[mtype] = TypeRows(tuple(f for f in want[mtype] if f in cols), clock(mtype, cols))
        if tr is None:
            b.skip(f"{mtype} records whose FMT lacks {', '.join(broken[mtype])} (damaged FMT)")
            continue
        if tr.time_field is not None:
            last = getattr(m, tr.time_field) * tr.scale
        tr.times.append(last)
        tr.rows.append(tr.get(m))
    if n_bad:
        b.skip("corrupt records", n_bad)
    return {k: v for k, v in types.items() if v is not None}


def _check_end(dflog, b: FlightBuilder) -> None:
    """Count a record cut by the end of the file (DFReader drops it silently)."""
    try:
        last = max((offs[-1], mtype) for mtype, offs in enumerate(dflog.offsets) if offs)
        ofs, mtype = last
        end = ofs + dflog.formats[mtype].len
        size = dflog.data_len
    except (AttributeError, ValueError, KeyError, IndexError):
        return
    if end > size:
        b.skip("record cut by the end of the file", 1)
        b.warn(f"the log ends inside a record (at byte {ofs} of {size}): read up to the cut")
    elif end < size:
        b.skip("record cut by the end of the file", 1)
        b.warn(f"{size - end} bytes after the last complete record (a cut record): ignored")


def timed_columns(path, types: Mapping[str, TypeRows], refusal: str) -> dict:
    """{type: :func:`columns`} with time in seconds from the earliest time stamp of the timed
    types (the log's start); a LogFormatError saying ``refusal`` when no record is timed."""
    timed = [min((x for x in tr.times if x == x), default=math.inf)
             for tr in types.values() if tr.time_field]
    t0 = min(timed, default=math.inf)
    if not math.isfinite(t0):
        raise LogFormatError(path, refusal)
    return {k: columns(tr, t0) for k, tr in types.items()}


def columns(tr: TypeRows, t0: float):
    """``(t, {field: array})`` of one type, ``t`` in seconds from ``t0``."""
    t = np.asarray(tr.times, float) - t0
    cols = {}
    if tr.rows:
        arr = list(zip(*tr.rows))
        for f, col in zip(tr.fields, arr):
            try:
                cols[f] = np.asarray(col, float)
            except (TypeError, ValueError):
                cols[f] = np.asarray(col, object)
    return t, cols


def instance0(t, cols, key):
    """The rows of instance 0 when the type has an instance field ``key``."""
    if key in cols:
        m = cols[key] == 0
        return t[m], {k: v[m] for k, v in cols.items()}
    return t, cols
