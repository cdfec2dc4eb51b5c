"""``droneid predict``: apply a saved model (identify's result.json) to other logs, report its error."""
from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from droneid.errors import ConfigError
from droneid.core.io_util import atomic_write_bytes
from droneid.core.lazy import lazy_module
from droneid.commands._common import add_log_options, log_options, print_json, read_logs, recorded_options_note

_predict = lazy_module("droneid.use.predict")
_report = lazy_module("droneid.report.predict")
_rollout_report = lazy_module("droneid.report.rollout")


def _horizons(text: str) -> tuple[int, ...]:
    import argparse
    try:
        hs = tuple(int(h) for h in text.split(",") if h.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"horizons must be comma-separated step counts, e.g. 1,10,50; "
                                         f"got {text!r}") from None
    if not hs or min(hs) < 1:
        raise argparse.ArgumentTypeError(f"horizons must be positive step counts; got {text!r}")
    return hs


def register(sub) -> None:
    p = sub.add_parser("predict", description="Apply the models of an identify result.json (or a single model file "
                                   "with --target) to other logs and report the RMSE per target and log, "
                                   "next to the empirical model's (as given and refit). --horizons adds "
                                   "multi-step prediction errors (see docs/use-the-model.md).")
    p.add_argument("model", metavar="RESULT_OR_MODEL.json", help="result.json of droneid identify, or a model file")
    p.add_argument("logs", nargs="+", metavar="LOG", help="log(s) to predict")
    p.add_argument("--target", default=None, help="target(s), comma separated (default: every target in the file)")
    p.add_argument("--ts", type=float, default=None, help="sampling period (default: the one identified with)")
    p.add_argument("--method", default=None, help="differentiator (default: the one identified with)")
    p.add_argument("--horizons", type=_horizons, default=None, metavar="H1,H2,...",
                   help="multi-step prediction: integrate the velocity models this many steps of the "
                        "log's rate from every in-flight sample (e.g. 1,10,50) and report the RMSE")
    p.add_argument("--open-loop", action="store_true",
                   help="the nanodrone benchmark's metric: simulate the full state open loop from the motor "
                        "speeds (a command-driven vehicle: from its motor commands and battery voltage through "
                        "the identified motor model) 50 steps from every start and report MAE at the --horizons "
                        "(default 1,10,50) and SimErr for the final model, nominal physics and the state held")
    p.add_argument("--plot", default=None, metavar="DIR",
                   help="with --horizons: write error-vs-horizon and predicted-trace PNGs into DIR")
    p.add_argument("--json", action="store_true", help="print the errors as one JSON line")
    add_log_options(p)
    p.epilog = ("Reader options: by default the logs are read with the options the result was identified "
                "with (its reader_options: --column, --topic, --body, --format, --sysid, --vehicle); options "
                "given here override them (a --column/--topic entry replaces the recorded entry of the same name).")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.plot and not args.horizons:
        raise ConfigError("--plot draws the multi-step prediction: give --horizons too (e.g. --horizons 1,10,50)")
    targets = [t.strip() for t in args.target.split(",")] if args.target else None
    models = _predict.load_models(args.model, targets)
    recorded = models.get("_reader_options") or {}
    flights = read_logs(args.logs, args, recorded=recorded)
    res = _predict.predict_flights(models, flights, ts=args.ts, method=args.method, horizons=args.horizons,
                          open_loop=args.open_loop)
    given = {k: v for k, v in log_options(args).items() if v is not None}
    if recorded or given:
        res = replace(res, reader_options={"recorded": recorded, "given": given})
    for w in res.warnings:
        print(f"droneid predict: warning: {w}", file=sys.stderr)
    written = []
    if args.plot and res.rollout is not None:
        for name, png in _rollout_report.horizon_figures(res.rollout.to_dict()).items():
            written.append(atomic_write_bytes(Path(args.plot) / f"{name}.png", png))
    if args.json:
        print_json(res.to_dict())
        return 0
    print(_report.text(res))
    if recorded:
        print("\n" + recorded_options_note(recorded, args, args.logs))
    for p in written:
        print(f"wrote {p}")
    return 0
