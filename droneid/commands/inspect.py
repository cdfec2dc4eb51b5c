"""``droneid inspect PATH``: what a log holds, after conversion to droneid's convention, and
whether it is fit for identification."""
from __future__ import annotations

import math

from ._common import add_log_options, print_json, read_logs


def register(sub):
    p = sub.add_parser(
        "inspect", help="show the format, signals, rates, segments and diagnostics of a flight log",
        description="Read a flight log (DataFlash .bin, MAVLink .tlog, PX4 .ulg, ROS 2 .mcap, "
                    "Motive or flat CSV) and show what droneid sees: format, vehicle, duration, each "
                    "signal with unit, rate, count, span and source, armed / in-flight intervals, "
                    "events, the damage that was skipped, and the log's fitness for the tilt-drag "
                    "and rotor-thrust models.")
    p.add_argument("path", help="the log file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.add_argument("--ts", type=float, default=0.05,
                   help="sampling period the fitness is judged for, in s (default 0.05)")
    add_log_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    (flight,) = read_logs([args.path], args)
    summary = flight.summary()
    summary["fitness"] = fitness_summary(flight, args.ts)
    if args.json:
        print_json(summary)
    else:
        print(render_text(summary))
    return 0


def fitness_summary(flight, ts: float) -> dict:
    """The fitness of one flight for the tilt-drag model and for a rotor-thrust model (the
    latter with the first rotor signal present: rpm1, motor1 or throttle)."""
    from ..fitness import ROTOR_THRUST_SIGNALS, TILT_DRAG_SIGNALS, assess
    out = {"tilt-drag": assess(flight, needed_signals=TILT_DRAG_SIGNALS, ts=ts).to_dict()}
    rotor = next((n for n in ("rpm1", "motor1", "throttle") if flight.has(n)), "rpm1")
    out["rotor-thrust"] = assess(flight, needed_signals=ROTOR_THRUST_SIGNALS + (rotor,), ts=ts).to_dict()
    return out


def _fmt(x, nd=2) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{nd}f}"


def render_text(s: dict) -> str:
    """A readable report of :meth:`Flight.summary` (pure: the summary in, text out)."""
    vtype = s.get("vehicle_type") or "unknown"
    decl = s.get("vehicle_declared")
    lines = [f"file:      {', '.join(s['files'])}",
             f"format:    {s['format']}",
             f"vehicle:   {s.get('vehicle') or '-'}",
             f"type:      {vtype}" + (f" (from {decl})" if decl else " (not declared by the log; --vehicle)"),
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
    if s.get("fitness"):
        lines.append("")
        lines.extend(render_fitness(s["fitness"]))
    return "\n".join(lines)


def render_fitness(fit: dict) -> list[str]:
    """The "fitness for the tilt-drag/rotor-thrust models" block (pure)."""
    any_fit = next(iter(fit.values()))
    ts = any_fit["ts"]
    fl = any_fit["flights"][0]
    tilt, speed = fl["tilt_deg"], fl["speed_ms"]
    out = [f"fitness for the tilt-drag/rotor-thrust models (Ts = {ts:g} s):",
           f"  airborne {_fmt(fl['airborne_s'], 1)} s, {fl['samples']} samples; tilt "
           f"{_fmt(tilt[0], 1)}..{_fmt(tilt[1], 1)} deg, horizontal speed {_fmt(speed[0])}.."
           f"{_fmt(speed[1])} m/s, yaw span {_fmt(fl['yaw_span_deg'], 0)} deg"]
    for model, f in fit.items():
        rates = ", ".join(f"{k} {_fmt(v, 1)} Hz" for k, v in f["flights"][0]["rates_hz"].items())
        out.append(f"  {model}: {'REFUSED' if f['problems'] else 'ok'} ({rates})")
        out.extend(f"    problem: {p}" for p in f["problems"])
        out.extend(f"    warning: {w}" for w in f["warnings"])
    return out
