"""``droneid dataset``: export the regression table a model would be fitted on."""
from __future__ import annotations

import sys

from droneid.errors import ConfigError
from droneid.commands import COMMANDS
from droneid.core.io_util import atomic_write_text
from droneid.core.lazy import lazy_module
from droneid.commands._common import add_log_options, log_options

_parsers = lazy_module("parsers")
_align = lazy_module("droneid.dataset.align")
_builder = lazy_module("droneid.dataset.builder")

HELP = COMMANDS["dataset"].help


def register(sub):
    p = sub.add_parser("dataset", description=HELP + ". Columns use canonical signal "
                       "names; the target (e.g. vx_dot) is a column; t is seconds from each log's "
                       "start and flight the log's name.")
    p.add_argument("logs", nargs="+", metavar="LOG", help="flight logs (any supported format)")
    p.add_argument("--target", default="vx_dot", help="derivative target, e.g. vx_dot, vy_dot, "
                   "vz_dot (default: vx_dot)")
    p.add_argument("--inputs", default=None, help="comma-separated input signals (default: the "
                   "paper's: vx,pitch,roll,yaw for vx_dot)")
    p.add_argument("--extras", default="none", help="further signals as columns: 'none' "
                   "(default), 'all' (every canonical signal the logs have) or a comma list")
    p.add_argument("--ts", type=float, default=0.05, help="grid period in seconds (default 0.05)")
    p.add_argument("--method", default="central", help="differentiator: central (default, as identify "
                   "and diagnose), forward (the paper's), savgol, spline")
    p.add_argument("--smooth-s", type=float, default=None, dest="window_s",
                   help="smoothing window in seconds for savgol/spline")
    p.add_argument("--in-flight", default="auto", choices=("auto", "all"),
                   help="auto: airborne part only, crashes trimmed (default); all: whole logs")
    p.add_argument("--window", action="append", default=None, metavar="START:END",
                   help="keep only this time window in seconds (repeatable)")
    p.add_argument("--merge", action="append", default=None, metavar="LOG2",
                   help="a second recording of the same flight (e.g. autopilot log with a mocap "
                   "CSV), clock-aligned and merged into LOG; give one per LOG, in order")
    p.add_argument("--offset", type=float, default=None, metavar="SECONDS",
                   help="clock offset to add to the --merge log (default: estimated)")
    add_log_options(p)   # --format, --topic, --body, --column, --sysid, --vehicle (for LOG, not --merge)
    p.add_argument("--max-samples", type=int, default=None, metavar="N",
                   help="keep N randomly chosen samples (in time order)")
    p.add_argument("--seed", type=int, default=0, help="seed for --max-samples (default 0)")
    p.add_argument("-o", "--output", required=True, metavar="TABLE.csv", help="output CSV")
    p.set_defaults(func=run)


def _windows(items):
    if not items:
        return None
    out = []
    for w in items:
        try:
            a, b = w.split(":")
            out.append((float(a), float(b)))
        except ValueError:
            raise ConfigError(f"--window must be START:END in seconds, e.g. 10:60. Got {w!r}.") from None
    return out


def _names(text):
    return [s.strip() for s in text.split(",") if s.strip()]


def run(args) -> int:
    if args.merge and len(args.merge) != len(args.logs):
        raise ConfigError(f"give one --merge per LOG ({len(args.logs)} logs, {len(args.merge)} --merge)")
    if args.offset is not None and not args.merge:
        raise ConfigError("--offset applies to --merge")
    flights = []
    for i, path in enumerate(args.logs):
        f = _parsers.read_flight(path, **log_options(args))
        if args.merge:
            f = _align.merge_flights(f, _parsers.read_flight(args.merge[i]), offset_s=args.offset)
        flights.append(f)
    e = args.extras.strip()
    extras = () if e == "none" else None if e == "all" else _names(e)
    builder = _builder.DatasetBuilder(ts=args.ts, method=args.method, window_s=args.window_s,
                             in_flight=args.in_flight, time_windows=_windows(args.window))
    ds = builder.build(flights, target=args.target,
                       inputs=_names(args.inputs) if args.inputs else None, extras=extras)
    if args.max_samples is not None:
        ds = _builder.subsample(ds, args.max_samples, seed=args.seed)
    df = ds.to_frame()
    atomic_write_text(args.output, df.to_csv(index=False, float_format="%.9g", lineterminator="\n"))
    if not args.quiet:
        err = sys.stderr
        span = ", ".join(f"{ds.sources[k]}: {ds.t[ds.flight == k].min():.2f}-{ds.t[ds.flight == k].max():.2f} s"
                         for k in sorted(set(ds.flight.tolist())))
        print(f"{args.output}: {len(ds)} samples of {ds.target_name} from {len(ds.sources)} log(s) "
              f"({span}); columns: {', '.join(df.columns)}", file=err)
        for note in ds.notes:
            print(f"  {note}", file=err)
    return 0
