"""``droneid inspect PATH``: what a log holds, after conversion to droneid's convention, and
whether it is fit for identification."""
from __future__ import annotations

import math

from droneid.core.lazy import lazy_module
from droneid.commands._common import add_log_options, print_json, read_logs

_fitness = lazy_module("droneid.dataset.suitability")
_flight = lazy_module("droneid.logs.flight")
_screening = lazy_module("droneid.logs.screening")
_consistency = lazy_module("droneid.logs.consistency")


def register(sub):
    p = sub.add_parser(
        "inspect",
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
    summary["signals"] = with_coverage(flight, summary["signals"])
    summary["fitness"] = _fitness.fitness_by_prior([flight], args.ts)
    summary["implausible"] = implausible_summary(flight)
    summary["consistency"] = _consistency.check_flight(flight).to_dict()
    if args.json:
        print_json(summary)
    else:
        print(render_text(summary))
    return 0


def implausible_summary(flight) -> dict:
    """{signal: {"count", "detail"}} of the canonical signals where screening
    (:mod:`droneid.logs.screening`) finds implausible samples or jumps: what identify, diagnose and
    predict leave out."""
    screens = _screening.screen_flight(flight, [n for n in flight.names if _flight.is_canonical(n)])
    return {n: {"count": sc.implausible, "detail": sc.describe()} for n, sc in screens.items() if sc.implausible}


def with_coverage(flight, rows: list) -> list:
    """The summary's signal rows (gap-aware rates: :attr:`droneid.logs.flight.Signal.rate_hz`) with,
    for signals in bursts, where they are (:func:`droneid.dataset.suitability.coverage`)."""
    out = []
    for g in rows:
        c = _fitness.coverage(flight[g["name"]])
        out.append(dict(g, bursts=c.describe()) if len(c.bursts) > 1 else g)
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
    bursty = [g for g in s["signals"] if g.get("bursts")]
    if bursty:
        lines.append("rates count the time a signal has data; in bursts: " + "; ".join(
            f"{', '.join(g['name'] for g in bursty if g['bursts'] == b)} {b}"
            for b in dict.fromkeys(g["bursts"] for g in bursty)))
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
    bad = s.get("implausible") or {}
    lines.append(f"implausible: {sum(v['count'] for v in bad.values())} sample(s) or jump(s) screened out "
                 f"before any fit (docs/estimates.md)" if bad else "implausible: none")
    lines.extend(f"  {v['detail']}" for v in bad.values())
    if s.get("consistency"):
        lines.append("")
        lines.extend(render_consistency(s["consistency"]))
    if s.get("fitness"):
        lines.append("")
        lines.extend(render_fitness(s["fitness"]))
    return "\n".join(lines)


def render_consistency(c: dict) -> list[str]:
    """The "conventions" block (pure): each finding in one line with its fix (identify and
    diagnose refuse such a log), then what each check measured or why it was skipped."""
    out = [f"conventions: {len(c['findings'])} MISTAKE(S): identify and diagnose refuse this log until fixed"
           if c["findings"] else "conventions: the redundant signals agree (droneid.logs.consistency)"]
    out.extend(f"  MISTAKE: {f['line']}" for f in c["findings"])
    out.extend(f"  {ch['status']:<8} {ch['name']}: {ch['detail']}" for ch in c["checks"])
    return out


def render_fitness(fit: dict) -> list[str]:
    """The "fitness for the tilt-drag/rotor-thrust models" block (pure): the vehicle evidence
    and the airborne basis once, then each prior's verdict, measurements and own warnings
    (warnings every prior shares are printed once)."""
    models = {k: v for k, v in fit.items() if k != "auto"}
    any_fit = next((v for v in models.values() if v.get("flights")), None)
    ts = next(iter(models.values()))["ts"]
    out = [f"fitness for the tilt-drag/rotor-thrust models (Ts = {ts:g} s):"]
    if any_fit is not None:
        fl = any_fit["flights"][0]
        ev = fl.get("vehicle_evidence") or {}
        tilt, speed = fl["tilt_deg"], fl["speed_ms"]
        out.append(f"  airborne: {fl.get('airborne_basis') or '-'}; tilt {_fmt(tilt[0], 1)}..{_fmt(tilt[1], 1)} deg, "
                   f"horizontal speed {_fmt(speed[0])}..{_fmt(speed[1])} m/s, yaw span "
                   f"{_fmt(fl['yaw_span_deg'], 0)} deg")
        if ev:
            why = "; ".join(ev["reasons"]) if ev["looks"] == "not a multirotor" else ""
            out.append(f"  flies like: {ev['looks']} ({ev['text']})" + (f": {why}" if why else ""))
    prefix = f"{any_fit['flights'][0]['name']}: " if any_fit is not None else None

    def bare(text):       # one flight: its name before every line says nothing
        return text[len(prefix):] if prefix and text.startswith(prefix) else text
    shared = None
    for f in models.values():
        w = set(f.get("warnings", ()))
        shared = w if shared is None else shared & w
    shared = shared or set()
    if len(models) < 2:
        shared = set()
    for model, f in models.items():
        if not f.get("applies", True):
            out.append(f"  {model}: does not apply: {f['problems'][0]}")
            continue
        if not f["flights"]:
            out.append(f"  {model}: not checked (a prior of a vehicle kind the check does not know)")
            continue
        fl = f["flights"][0]
        rates = ", ".join(f"{k} {_fmt(v, 1)} Hz" for k, v in fl["rates_hz"].items())
        verdict = "REFUSED" if f["problems"] else "ok"
        out.append(f"  {model}: {verdict} (airborne {_fmt(fl['airborne_s'], 1)} s, {fl['samples']} samples; {rates})")
        out.extend(f"    problem: {bare(p)}" for p in f["problems"])
        out.extend(f"    warning: {bare(w)}" for w in f["warnings"] if w not in shared)
    out.extend(f"  warning: {bare(w)}" for w in sorted(shared, key=lambda w: next(
        i for i, x in enumerate(next(iter(models.values()))["warnings"]) if x == w)))
    if "auto" in fit:
        out.append(f"  --prior auto chooses: {fit['auto']['prior']} ({fit['auto']['reason']})")
    return out
