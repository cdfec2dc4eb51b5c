"""``droneid inspect PATH``: what a log holds, after conversion to droneid's convention."""
from __future__ import annotations

import math

from ..errors import ConfigError
from ._common import print_json


def register(sub):
    p = sub.add_parser(
        "inspect", help="show the format, signals, rates, segments and diagnostics of a flight log",
        description="Read a flight log (DataFlash .bin, MAVLink .tlog, PX4 .ulg, ROS 2 .mcap, "
                    "Motive or flat CSV) and show what droneid sees: format, vehicle, duration, each "
                    "signal with unit, rate, count, span and source, armed / in-flight intervals, "
                    "events and the damage that was skipped.")
    p.add_argument("path", help="the log file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.add_argument("--format", dest="log_format", default=None,
                   help="skip format detection (dataflash, tlog, ulog, mcap, motive_csv, csv)")
    p.add_argument("--topic", action="append", default=[], metavar="ROLE=TOPIC",
                   help="MCAP: use TOPIC for ROLE (pose, twist, odom, imu, battery, rc); repeatable")
    p.add_argument("--body", default=None, help="Motive CSV: the rigid body to read")
    p.add_argument("--column", action="append", default=[], metavar="NAME=COLUMN",
                   help="flat CSV: read canonical signal NAME from COLUMN; repeatable")
    p.add_argument("--sysid", type=int, default=None, help="tlog: the vehicle's MAVLink system id")
    p.set_defaults(func=run)


def _pairs(items, what) -> dict | None:
    out = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--{what} expects NAME=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out or None


def run(args) -> int:
    from parsers import read_flight
    flight = read_flight(args.path, format=args.log_format, topics=_pairs(args.topic, "topic"),
                         body=args.body, column_map=_pairs(args.column, "column"), sysid=args.sysid)
    summary = flight.summary()
    if args.json:
        print_json(summary)
    else:
        print(render_text(summary))
    return 0


def _fmt(x, nd=2) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{nd}f}"


def render_text(s: dict) -> str:
    """A readable report of :meth:`Flight.summary` (pure: the summary in, text out)."""
    lines = [f"file:      {', '.join(s['files'])}",
             f"format:    {s['format']}",
             f"vehicle:   {s.get('vehicle') or '-'}",
             f"firmware:  {s.get('firmware') or '-'}",
             f"duration:  {_fmt(s['duration_s'], 1)} s", ""]
    head = ("signal", "unit", "rate Hz", "count", "start s", "end s", "source")
    rows = [(g["name"], g["unit"], _fmt(g["rate_hz"], 1), str(g["count"]), _fmt(g["start_s"]),
             _fmt(g["end_s"]), g["source"]) for g in s["signals"]]
    widths = [max(len(r[i]) for r in rows + [head]) for i in range(len(head))]
    right = {2, 3, 4, 5}

    def line(r):
        return "  ".join(c.rjust(w) if i in right else c.ljust(w)
                         for i, (c, w) in enumerate(zip(r, widths))).rstrip()
    lines.append(line(head))
    lines.append(line(tuple("-" * w for w in widths)))
    lines.extend(line(r) for r in rows)
    lines.append("")
    for label in ("armed", "in_flight"):
        if label in s["segments"]:
            iv = s["segments"][label]
            text = ", ".join(f"{_fmt(a, 1)}-{_fmt(b, 1)} s" for a, b in iv) or "none"
        else:
            text = "unknown"
        lines.append(f"{label + ':':<11}{text}")
    for label, iv in s["segments"].items():
        if label not in ("armed", "in_flight"):
            lines.append(f"{label + ':':<11}" + ", ".join(f"{_fmt(a, 1)}-{_fmt(b, 1)} s" for a, b in iv))
    if s["events"]:
        lines.append("")
        lines.append(f"events ({len(s['events'])}):")
        shown = s["events"][:30]
        for e in shown:
            lines.append(f"  {_fmt(e['t_s'], 2):>9} s  {e['kind']:<9} {e['text']}".rstrip())
        if len(s["events"]) > len(shown):
            lines.append(f"  ... {len(s['events']) - len(shown)} more (see --json)")
    if s["notes"]:
        lines.append("")
        lines.append("notes:")
        lines.extend(f"  - {n}" for n in s["notes"])
    d = s["diagnostics"]
    lines.append("")
    if d["total_skipped"] or d["warnings"]:
        lines.append(f"diagnostics: {d['total_skipped']} skipped")
        for k, n in d["skipped"].items():
            lines.append(f"  {n:>8}  {k}")
        for w in d["warnings"]:
            lines.append(f"  warning: {w}")
    else:
        lines.append("diagnostics: nothing skipped")
    return "\n".join(lines)
