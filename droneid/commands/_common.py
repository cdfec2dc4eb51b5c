"""Helpers shared by CLI commands (printing is allowed here: this is the CLI layer)."""
from __future__ import annotations

import json
import os
import sys
import time

from droneid.errors import ConfigError, DroneIdError
from droneid.core.lazy import lazy_module

_parsers = lazy_module("parsers")            # the readers (pymavlink, pyulog, mcap): once a log is read
_flight = lazy_module("droneid.logs.flight")
_frames = lazy_module("droneid.core.frames")
_predict = lazy_module("droneid.use.predict")


class ProgressBar:
    """A text progress bar on stderr; call it as ``bar(done, total, message="")``.

    Library code takes an optional ``progress`` callable with this signature and never prints.
    Silent when ``quiet`` or when stderr is not a terminal and ``force`` is false (then it prints
    one line per ~10 % instead of redrawing).
    """

    def __init__(self, label: str, quiet: bool = False, stream=None):
        self.label = label
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.t0 = time.perf_counter()
        self._last_decile = -1
        self._first = None  # (done, elapsed s) at the first call with done > 0
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def __call__(self, done: int, total: int, message: str = "") -> None:
        if self.quiet or total <= 0:
            return
        frac = min(max(done / total, 0.0), 1.0)
        elapsed = time.perf_counter() - self.t0
        # the time left comes from the pace since the first result, not since the start: the
        # first result may carry a one-off cost (numba compiling the SNGP kernels, ~40 s)
        if self._first is None and done > 0:
            self._first = (done, elapsed)
        eta = float("nan")
        if self._first is not None and done > self._first[0] and elapsed > self._first[1]:
            pace = (done - self._first[0]) / (elapsed - self._first[1])
            eta = (total - done) / pace
        text = f"{self.label}: {done}/{total} ({100 * frac:5.1f} %) {elapsed:6.1f} s"
        if frac < 1 and eta == eta:
            text += f", ~{eta:.0f} s left"
        if message:
            text += f"  {message}"
        if self._tty:
            width = 24
            bar = "#" * int(round(width * frac)) + "-" * (width - int(round(width * frac)))
            self.stream.write(f"\r[{bar}] {text}\033[K")
            if done >= total:
                self.stream.write("\n")
        else:
            decile = int(frac * 10)
            if decile != self._last_decile or done >= total:
                self._last_decile = decile
                self.stream.write(text + "\n")
        self.stream.flush()


def print_json(obj) -> None:
    """Print one JSON object on one line to stdout."""
    print(json.dumps(obj, default=_json_default, allow_nan=False))


def _json_default(o):
    import numpy as np
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"cannot serialise {type(o).__name__}")


# -- reading logs: the options every command that reads flight logs shares -------------------
def add_log_options(p, *, with_format: bool = True) -> None:
    """Add the reader options (``--format`` unless the command has its own, ``--topic``,
    ``--body``, ``--column``, ``--sysid``, ``--world-frame``, ``--body-frame``, ``--time-unit``,
    ``--scale``, ``--vehicle``) to a subcommand parser."""
    if with_format:
        p.add_argument("--format", dest="log_format", default=None,
                       help="skip format detection: a reader's format name (docs/logs.md; an unknown "
                            "name lists the installed readers, plug-ins included)")
    p.add_argument("--topic", action="append", default=[], metavar="ROLE=TOPIC",
                   help="MCAP: use TOPIC for ROLE (pose, twist, odom, imu, battery, rc) or for a "
                        "canonical signal (throttle=/rc[2], rpm1=/esc/rpm1); repeatable")
    p.add_argument("--body", default=None, help="Motive CSV: the rigid body to read")
    p.add_argument("--column", action="append", default=[], metavar="CANON=COLUMN",
                   help="flat CSV: read canonical signal CANON (x, vx, throttle, rpm1, motor1, ...) "
                        "from COLUMN; repeatable")
    p.add_argument("--sysid", type=int, default=None, help="tlog: the vehicle's MAVLink system id")
    p.add_argument("--world-frame", default=None, choices=_frames.WORLD_FRAMES,
                   help="the log's world frame when it is not droneid's ENU: ned = north, east, down "
                        "(position and velocity converted; docs/logs.md, convention checks)")
    p.add_argument("--body-frame", default=None, choices=_frames.BODY_FRAMES,
                   help="the log's body frame when it is not droneid's FLU: frd = forward, right, down "
                        "(body rates and accelerations; with --world-frame ned the attitude too)")
    p.add_argument("--time-unit", default=None, choices=tuple(_flight.TIME_UNITS),
                   help="the unit of the time stamps a reader takes as seconds (e.g. ms: a 70 s flight "
                        "read as 70 000 s)")
    p.add_argument("--scale", action="append", default=[], metavar="NAME=FACTOR",
                   help="multiply signal NAME as read by FACTOR (a number, pi, a/b): vx=1/3.6 for km/h, "
                        "wx=pi/180 for deg/s, yaw=-1 for a clockwise heading; repeatable")
    p.add_argument("--vehicle", default=None,
                   choices=_flight.VEHICLE_TYPES,
                   help="the vehicle type, when the log does not declare it (mocap CSV, MCAP) or "
                        "to override its declaration")


def _pairs(items, what) -> dict | None:
    out = {}
    for item in items or ():
        if "=" not in item:
            raise ConfigError(f"--{what} expects NAME=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out or None


def log_options(args) -> dict:
    """read_flight keyword arguments from the options of :func:`add_log_options`."""
    return {"format": getattr(args, "log_format", None),
            "topics": _pairs(getattr(args, "topic", None), "topic"),
            "body": getattr(args, "body", None),
            "column_map": _pairs(getattr(args, "column", None), "column"),
            "sysid": getattr(args, "sysid", None),
            "vehicle": getattr(args, "vehicle", None),
            "world_frame": getattr(args, "world_frame", None),
            "body_frame": getattr(args, "body_frame", None),
            "time_unit": getattr(args, "time_unit", None),
            "scales": _pairs(getattr(args, "scale", None), "scale")}


def read_logs(paths, args=None, recorded: dict | None = None) -> list:
    """Read every log (format from its content unless ``--format``), with the reader options.

    ``recorded``: reader options a result was identified with (``reader_options`` of identify's
    result.json, as :func:`log_options` gives them); they apply by default and the options given
    in ``args`` override them (see :func:`merged_log_options`)."""
    opts = log_options(args) if args is not None else {}
    if not recorded:
        return [_parsers.read_flight(p, **opts) for p in paths]
    flights = []
    for p in paths:
        merged = merged_log_options(recorded, opts, p)
        try:
            flights.append(_parsers.read_flight(p, **merged))
        except DroneIdError as exc:
            applied = _from_record(recorded, opts, merged)
            if not applied:
                raise
            raise ConfigError(f"{exc} (read with the reader options the model was identified with: "
                              f"{options_text(applied)}; options given here override them, e.g. "
                              f"--column NAME=NAME reads a column under its own name)") from None
    return flights


#: reader options that are maps (``--column``/``--topic``/``--scale``): given entries override recorded ones
_MAP_OPTIONS = ("topics", "column_map", "scales")
#: reader options every format takes (read_flight's own); the others are a reader's own options
_ANY_FORMAT = ("format", "vehicle", "world_frame", "body_frame", "time_unit", "scales")
_MAP_FLAGS = {"column_map": "--column", "topics": "--topic", "scales": "--scale"}


def merged_log_options(recorded: dict, given: dict, path) -> dict:
    """read_flight keyword arguments for one log: ``given`` (:func:`log_options` of the command
    line) over ``recorded`` (the options a result was identified with).

    A given scalar replaces the recorded one; a given ``--column``/``--topic`` entry replaces the
    recorded entry of the same name and keeps the others. A recorded option the log's reader does
    not take (a ``--column`` map recorded on CSV logs, applied to a ULog) is left out; a given one
    is kept, and the reader refuses it as it would without a record."""
    out = {k: v for k, v in recorded.items() if k in _predict.READER_OPTION_TYPES and v is not None and v != {}}
    for k, v in given.items():
        if v is None:
            continue
        out[k] = {**out[k], **v} if k in _MAP_OPTIONS and isinstance(out.get(k), dict) else v
    own = [k for k in out if k not in _ANY_FORMAT and given.get(k) is None]
    if own:
        accepted = _reader_accepts(out.get("format"), path)
        if accepted is not None:
            out = {k: v for k, v in out.items() if k not in own or k in accepted}
    return out


def _from_record(recorded: dict, given: dict, merged: dict) -> dict:
    """The part of ``merged`` that came from the record (not given on the command line)."""
    out = {}
    for k, v in merged.items():
        if k not in recorded:
            continue
        if k in _MAP_OPTIONS and isinstance(v, dict):
            rest = {n: c for n, c in v.items() if n not in (given.get(k) or {})}
            if rest:
                out[k] = rest
        elif given.get(k) is None:
            out[k] = v
    return out


def recorded_options_note(recorded: dict, args, paths) -> str:
    """One line saying which logs were read with the reader options a result recorded (and
    which took none of them: a reader that has no such option), '' when none was recorded."""
    if not recorded:
        return ""
    given = log_options(args)
    by_text: dict[str, list[str]] = {}
    for p in paths:
        by_text.setdefault(options_text(_from_record(recorded, given, merged_log_options(recorded, given, p))),
                           []).append(str(p))
    parts = []
    for text, logs in by_text.items():
        which = "every log" if len(by_text) == 1 else ", ".join(logs)
        parts.append(f"{which}: {text}" if text else
                     f"{which}: none of them (its reader takes no such option)")
    return ("read with the reader options the model was identified with (options given here override "
            "them): " + "; ".join(parts))


def _reader_accepts(fmt, path) -> tuple | None:
    """The options of the reader that reads ``path`` (None when it cannot be told: read_flight
    then reports the problem with the file)."""
    try:
        if fmt is None:
            if not os.path.isfile(path):
                return None
            fmt = _parsers.detect_format(path)
        return tuple(_parsers.READERS[fmt].options)
    except (DroneIdError, OSError, KeyError):
        return None


def options_text(opts: dict) -> str:
    """Reader options as the command-line words that give them (``--column vx=vel_e ...``)."""
    flags = {"format": "--format", "body": "--body", "sysid": "--sysid", "vehicle": "--vehicle",
             "world_frame": "--world-frame", "body_frame": "--body-frame", "time_unit": "--time-unit"}
    words = []
    for k, v in opts.items():
        if v is None or v == {}:
            continue
        if k in _MAP_OPTIONS:
            flag = _MAP_FLAGS[k]
            words += [f"{flag} {name}={value}" for name, value in v.items()]
        else:
            words.append(f"{flags.get(k, '--' + k)} {v}")
    return " ".join(words)
