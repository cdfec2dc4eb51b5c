"""Flight-log readers and writers. Every reader returns one :class:`droneid.flight.Flight`
in droneid's internal convention (see :mod:`droneid.frames`).

``read_flight(path)`` recognises the format by the file's CONTENT (magic bytes, header rows);
the extension only breaks ties. Readers are registered by format name in :data:`READERS`.
"""
from __future__ import annotations

import importlib
import logging
import os
from collections.abc import Callable, Mapping
from dataclasses import replace
from types import MappingProxyType

from droneid.errors import ConfigError, DroneIdError, LogFormatError, check_choice, did_you_mean
from droneid.flight import VEHICLE_TYPES, Flight

from ._guard import captured_output

log = logging.getLogger(__name__)

__all__ = ["read_flight", "detect_format", "get_reader", "READERS", "FORMATS"]

#: format name -> "module:function" of its reader (imported on first use).
READERS: Mapping[str, str] = MappingProxyType({
    "dataflash": "parsers.dataflash_log:read_dataflash",
    "tlog": "parsers.mavlink_log:read_tlog",
    "ulog": "parsers.ulog_log:read_ulog",
    "mcap": "parsers.mcap_log:read_mcap",
    "motive_csv": "parsers.mocap_csv:read_motive_csv",
    "csv": "parsers.mocap_csv:read_flat_csv",
})
FORMATS = tuple(READERS)

_EXT = {".bin": "dataflash", ".tlog": "tlog", ".ulg": "ulog", ".mcap": "mcap", ".csv": "csv"}


def get_reader(name: str) -> Callable[..., Flight]:
    """The reader function registered under a format name (ConfigError for unknown names)."""
    if name not in READERS:
        raise ConfigError(f"unknown log format {name!r}; known formats: {', '.join(FORMATS)}"
                          + did_you_mean(str(name), FORMATS))
    mod, func = READERS[name].split(":")
    return getattr(importlib.import_module(mod), func)


def _looks_like_tlog(head: bytes) -> bool:
    """MAVLink frames, each after an 8-byte big-endian µs UNIX time stamp, make up most of the
    head of the file (a few garbage bytes are tolerated; the reader counts them)."""
    pos, frames, garbage = 0, 0, 0
    n = len(head)
    while pos + 10 <= n:
        magic = head[pos + 8]
        ts = int.from_bytes(head[pos:pos + 8], "big")
        if magic in (0xFE, 0xFD) and 946684800_000000 < ts < 4102444800_000000:  # 2000..2100
            ln = head[pos + 9] + (8 if magic == 0xFE else 12)
            if magic == 0xFD and pos + 10 < n and head[pos + 10] & 1:
                ln += 13
            frames += 1
            pos += 8 + ln
        else:
            pos += 1
            garbage += 1
    return frames >= 1 and garbage <= 0.25 * max(pos, 1) and (frames >= 2 or n < 64)


def _csv_kind(head: bytes) -> str | None:
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = head.decode("latin-1")
    if "\x00" in text:
        return None
    first = text.splitlines()[0] if text.splitlines() else ""
    cells = [c.strip().strip('"') for c in first.split(",")]
    if cells and cells[0] == "Format Version":
        return "motive_csv"
    if len(cells) >= 2 and sum(1 for c in cells if c and not _is_number(c)) >= 2:
        return "csv"
    return None


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def detect_format(path) -> str:
    """The format name of a log file, from its content (extension only as a tie-breaker).

    Raises LogFormatError for an empty file or unrecognised content.
    """
    path = os.fspath(path)
    with open(path, "rb") as f:
        head = f.read(4096)
    if not head:
        raise LogFormatError(path, "the file is empty")
    if head.startswith(b"ULog\x01\x12\x35"):
        return "ulog"
    if head.startswith(b"\x89MCAP0\r\n"):
        return "mcap"
    if head[:2] == b"\xa3\x95" and len(head) >= 3:
        return "dataflash"
    if len(head) >= 10 and _looks_like_tlog(head):
        return "tlog"
    kind = _csv_kind(head)
    if kind:
        return kind
    ext = os.path.splitext(path)[1].lower()
    hint = f" (the extension says {_EXT[ext]!r} but the content does not match)" if ext in _EXT else ""
    raise LogFormatError(path, "unrecognised log format: not DataFlash, tlog, ULog, MCAP or CSV"
                         + hint)


def read_flight(path, *, format: str | None = None, topics: Mapping[str, str] | None = None,
                body: str | None = None, column_map: Mapping[str, str] | None = None,
                sysid: int | None = None, vehicle: str | None = None) -> Flight:
    """Read one flight log into a :class:`Flight` (internal convention: ENU/FLU, SI, seconds).

    Parameters
    ----------
    path : the log file.
    format : a name from :data:`FORMATS` to skip detection.
    topics : MCAP role -> topic overrides, e.g. ``{"pose": "/cub1/pose"}``.
    body : the rigid body to read from a Motive CSV with several bodies.
    column_map : CSV canonical name -> column name overrides, e.g. ``{"x": "pos_x"}``.
    sysid : MAVLink system id of the vehicle in a tlog (default: the vehicle's heartbeat).
    vehicle : the vehicle type (one of :data:`droneid.flight.VEHICLE_TYPES`) when the log does not
        declare it (mocap CSV, MCAP) or declares it wrongly; the log's declaration is kept in
        ``vehicle_declared``.
    """
    if vehicle is not None:
        check_choice("vehicle", vehicle, VEHICLE_TYPES, "read_flight")
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(2, "No such file or directory", path)
    if os.path.isdir(path):
        raise LogFormatError(path, "is a directory, not a log file")
    fmt = format or detect_format(path)
    reader = get_reader(fmt)
    opts = {}
    if fmt == "mcap":
        opts["topics"] = topics
    elif fmt == "motive_csv":
        opts["body"] = body
    elif fmt == "csv":
        opts["column_map"] = column_map
    elif fmt == "tlog":
        opts["sysid"] = sysid
    unused = {"topics": topics, "body": body, "column_map": column_map, "sysid": sysid}
    bad = [k for k, v in unused.items() if v is not None and k not in opts]
    if bad:
        raise ConfigError(f"option(s) {', '.join(bad)} do not apply to {fmt} logs ({path})")
    flight = _guarded(reader, path, fmt, opts)
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
        with captured_output() as cap:
            flight = reader(path, **opts)
    except (DroneIdError, FileNotFoundError, PermissionError):
        raise
    except Exception as exc:  # noqa: BLE001 - the boundary: a damaged file must not traceback
        msg = str(exc).splitlines()[0][:200] if str(exc) else ""
        extra = f"; the {fmt} library reported {len(cap.lines)} problems first" if cap.lines else ""
        raise LogFormatError(path, f"unreadable {fmt} log, damaged beyond what the reader "
                                   f"skips ({type(exc).__name__}: {msg}){extra}") from exc
    lines = cap.lines
    if lines:
        first = lines[0].strip()[:100]
        diag = flight.diagnostics.add(warnings=[
            f"{len(lines)} lines of reader library output suppressed (first: {first!r})"])
        flight = replace(flight, diagnostics=diag)
    if flight.diagnostics.warnings:
        log.warning("%s: %d reader warning(s), %d records/samples skipped (details: droneid "
                    "inspect)", path, len(flight.diagnostics.warnings), flight.diagnostics.total_skipped)
    return flight
