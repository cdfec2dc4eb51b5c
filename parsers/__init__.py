"""Flight-log readers and writers. Every reader returns one :class:`droneid.logs.flight.Flight`
in droneid's internal convention (see :mod:`droneid.core.frames`).

``read_flight(path)`` recognises the format by the file's CONTENT (magic bytes, header rows);
the extension only names it in errors. A format is a plug-in: any module of this package that
exports ``READER`` (a :class:`~parsers._registry.Reader`: name, ``read``, ``sniff``, options) is
found by :data:`READERS`; adding a format is one new module (docs/extending.md).
"""
from __future__ import annotations

import logging
import os
import warnings
from collections.abc import Callable, Mapping
from dataclasses import replace

import numpy as np

from droneid.errors import ConfigError, DroneIdError, LogFormatError, check_choice, did_you_mean
from droneid.logs.flight import VEHICLE_TYPES, Flight

from ._convention import convert
from ._guard import captured_output
from ._registry import Reader, clear_cache, discover

log = logging.getLogger(__name__)

__all__ = ["read_flight", "detect_format", "get_reader", "READERS", "FORMATS", "Reader",
           "clear_cache"]


def __getattr__(name: str):
    """``READERS`` (format name -> :class:`Reader`, read-only) and ``FORMATS`` (the names, in
    detection order), discovered on first use."""
    if name == "READERS":
        return discover()
    if name == "FORMATS":
        return tuple(r.name for r in _in_order())
    raise AttributeError(f"module 'parsers' has no attribute {name!r}")


def _in_order() -> list[Reader]:
    return sorted(discover().values(), key=lambda r: (r.order, r.name))


def _spec(name: str) -> Reader:
    readers = discover()
    if name not in readers:
        names = [r.name for r in _in_order()]
        raise ConfigError(f"unknown log format {name!r}; known formats: {', '.join(names)}"
                          + did_you_mean(str(name), names))
    return readers[name]


def get_reader(name: str) -> Callable[..., Flight]:
    """The reader function registered under a format name (ConfigError for unknown names)."""
    return _spec(name).read


def detect_format(path) -> str:
    """The format name of a log file, from its content: the first registered reader (in
    ``order``) whose ``sniff`` accepts the file's first 4096 bytes.

    Raises LogFormatError for an empty file or unrecognised content.
    """
    path = os.fspath(path)
    with open(path, "rb") as f:
        head = f.read(4096)
    if not head:
        raise LogFormatError(path, "the file is empty")
    readers = _in_order()
    for r in readers:
        if r.sniff(head):
            return r.name
    ext = os.path.splitext(path)[1].lower()
    claim = [r.name for r in readers if ext in r.extensions]
    hint = (f" (the extension says {' or '.join(map(repr, claim))} but the content does not match)"
            if claim else "")
    raise LogFormatError(path, "unrecognised log format: not "
                         + ", ".join(r.name for r in readers) + hint)


def read_flight(path, *, format: str | None = None, topics: Mapping[str, str] | None = None,
                body: str | None = None, column_map: Mapping[str, str] | None = None,
                sysid: int | None = None, vehicle: str | None = None, world_frame: str | None = None,
                body_frame: str | None = None, time_unit: str | None = None,
                scales: Mapping[str, object] | None = None, **options) -> Flight:
    """Read one flight log into a :class:`Flight` (internal convention: ENU/FLU, SI, seconds).

    Parameters
    ----------
    path : the log file.
    format : a name from :data:`FORMATS` to skip detection.
    topics : MCAP role -> topic overrides, e.g. ``{"pose": "/cub1/pose"}``.
    body : the rigid body to read from a Motive CSV with several bodies.
    column_map : CSV canonical name -> column name overrides, e.g. ``{"x": "pos_x"}``.
    sysid : MAVLink system id of the vehicle in a tlog (default: the vehicle's heartbeat).
    vehicle : the vehicle type (one of :data:`droneid.logs.flight.VEHICLE_TYPES`) when the log does not
        declare it (mocap CSV, MCAP) or declares it wrongly; the log's declaration is kept in
        ``vehicle_declared``.
    world_frame, body_frame, time_unit, scales : the log's own convention when it is not droneid's
        (``"ned"``, ``"frd"``, ``"ms"``, ``{"vx": "1/3.6"}``): converted once, after the reader,
        for every format (:func:`parsers._convention.convert`; docs/logs.md, "Convention checks").
    options : any other keyword option of a plug-in reader (its ``Reader.options``).
    """
    if vehicle is not None:
        check_choice("vehicle", vehicle, VEHICLE_TYPES, "read_flight")
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(2, "No such file or directory", path)
    if os.path.isdir(path):
        raise LogFormatError(path, "is a directory, not a log file")
    fmt = format or detect_format(path)
    spec = _spec(fmt)
    given = {"topics": topics, "body": body, "column_map": column_map, "sysid": sysid, **options}
    opts = {k: v for k, v in given.items() if v is not None}
    bad = [k for k in opts if k not in spec.options]
    if bad:
        raise ConfigError(f"option(s) {', '.join(bad)} do not apply to {fmt} logs ({path})")
    reader = spec.read
    flight = _guarded(reader, path, fmt, opts)
    flight = convert(flight, world_frame=world_frame, body_frame=body_frame, time_unit=time_unit, scale=scales)
    if vehicle is not None:
        prov = flight.provenance
        said = f"; the log declares {prov.vehicle_declared}" if prov.vehicle_declared else ""
        flight = replace(flight, provenance=replace(
            prov, vehicle_type=vehicle, vehicle_declared=f"--vehicle {vehicle}{said}"))
    return flight


def _guarded(reader, path: str, fmt: str, opts: dict) -> Flight:
    """Run a reader so that nothing escapes but a Flight or a DroneIdError (the one wrapper).

    * whatever the third-party libraries print (pymavlink's "bad header" lines, pyulog's
      "File corruption detected") is captured and counted into the Flight's diagnostics;
    * any other exception (a bug on a damaged file: KeyError, struct.error, a loop guard, ...)
      becomes a LogFormatError naming the file, the problem, and the output captured so far;
    * one warning line is logged when the reader met damage (the details are in the Flight).
    """
    try:
        # damaged numbers (1e308, zero quaternions) become inf / nan, which the readers count as
        # non-finite samples: no numpy warning; a library's Python warnings are kept as data
        with captured_output() as cap, np.errstate(over="ignore", invalid="ignore", divide="ignore"), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            flight = reader(path, **opts)
    except (DroneIdError, FileNotFoundError, PermissionError):
        raise
    except Exception as exc:  # noqa: BLE001 - the boundary: a damaged file must not traceback
        msg = str(exc).splitlines()[0][:200] if str(exc) else ""
        extra = f"; the {fmt} library reported {len(cap.lines)} problems first" if cap.lines else ""
        raise LogFormatError(path, f"unreadable {fmt} log, damaged beyond what the reader "
                                   f"skips ({type(exc).__name__}: {msg}){extra}") from exc
    lines = cap.lines
    if caught:
        first = f"{caught[0].category.__name__}: {str(caught[0].message)[:100]}"
        flight = replace(flight, diagnostics=flight.diagnostics.add(warnings=[
            f"{len(caught)} warning(s) of the reader libraries suppressed (first: {first!r})"]))
    if lines:
        first = lines[0].strip()[:100]
        diag = flight.diagnostics.add(warnings=[
            f"{len(lines)} lines of reader library output suppressed (first: {first!r})"])
        flight = replace(flight, diagnostics=diag)
    if flight.diagnostics.warnings:
        log.warning("%s: %d reader warning(s), %d records/samples skipped (details: droneid "
                    "inspect)", path, len(flight.diagnostics.warnings), flight.diagnostics.total_skipped)
    return flight
