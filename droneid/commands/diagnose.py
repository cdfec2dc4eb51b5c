"""``droneid diagnose``: find what a prior model lacks, add it, report the error before and after."""
from __future__ import annotations

import argparse

from droneid.errors import ConfigError
from droneid.core.lazy import lazy_module
from droneid.commands._common import ProgressBar, add_log_options, print_json, read_logs

_diagnose = lazy_module("droneid.diagnosis.diagnose")
_report = lazy_module("droneid.report.diagnose")
_effects = lazy_module("priors.effects")


def register(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        description="Fit the prior, score a catalogue of candidate effects (wind, quadratic drag, "
                    "attitude bias/delay, ...) against the residual with blocked cross-validation on "
                    "the TRAINING flights, add the significant ones in order, and search the rest of "
                    "the residual with SNGP. Test flights are reported, never used for a choice. "
                    "Effects whose signals are missing are reported as untestable.")
    p.add_argument("train", nargs="+", metavar="TRAIN_LOG", help="training flight log(s)")
    p.add_argument("--test", nargs="+", metavar="TEST_LOG", default=None, help="test flight log(s)")
    p.add_argument("--prior", default="auto",
                   help="prior model: auto (rotor-thrust when the logs have motor speeds, motor "
                        "commands, thrust or throttle, else tilt-drag; as identify), a built-in "
                        "name or file.toml:name (default: auto)")
    p.add_argument("--target", default=None,
                   help="comma-separated targets (default: the prior's among vx_dot, vy_dot, vz_dot)")
    p.add_argument("--allow-measured-derivatives", action="store_true",
                   help="let effects and the open-ended search use measured derivatives (IMU ax ay "
                        "az, differenced vz_dot); the resulting model cannot be simulated")
    p.add_argument("--report", metavar="DIR", help="write diagnosis.json/.md/.html and plots here")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("--effects", metavar="TOML", help="extra user-defined effects (TOML)")
    p.add_argument("--only", metavar="IDS", help="comma-separated effect ids to test (default: all)")
    p.add_argument("--ts", type=float, default=0.05, help="dataset grid step in s (default 0.05)")
    p.add_argument("--method", default="central", help="differentiator (default central)")
    p.add_argument("--blocks", type=int, default=None,
                   help="cross-validation time blocks per flight (default: ~60 samples per block, 16..30)")
    p.add_argument("--alpha", type=float, default=0.01,
                   help="family-wise significance level of the block test, Holm-controlled over every candidate (default 0.01)")
    p.add_argument("--min-improvement", type=float, default=0.01,
                   help="minimum relative CV-RMSE improvement to add an effect (default 0.01)")
    p.add_argument("--max-steps", type=int, default=5, help="most effects added (default 5)")
    p.add_argument("--generations", "--sngp-generations", dest="generations", type=int, default=5000,
                   metavar="G", help="open-ended SNGP search budget per run (3 runs per target); 0 "
                                     "disables it (default 5000; --sngp-generations is the old name)")
    p.add_argument("--seed", type=int, default=0, help="seed of the open-ended search")
    p.add_argument("--format", dest="log_format", default=None, help="force the log format")
    add_log_options(p, with_format=False)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    targets = None
    if args.target is not None:
        targets = tuple(t.strip() for t in args.target.split(",") if t.strip())
        if not targets:
            raise ConfigError("--target: no targets given")
    user = None
    if args.effects:
        user = _effects.load_effects(args.effects)
    only = tuple(s.strip() for s in args.only.split(",")) if args.only else None
    cfg = _diagnose.DiagnoseConfig(ts=args.ts, method=args.method, n_blocks=args.blocks, alpha=args.alpha,
                         min_rel_improvement=args.min_improvement, max_steps=args.max_steps,
                         generations=args.generations, seed=args.seed, effects=only,
                         allow_measured_derivatives=args.allow_measured_derivatives)
    train = read_logs(args.train, args)
    test = read_logs(args.test, args) if args.test else None
    bar = ProgressBar("diagnose", quiet=args.quiet or args.json)
    result = _diagnose.diagnose(train, test, prior=args.prior, targets=targets, config=cfg, user_effects=user,
                      progress=bar)
    if args.report:
        _report.write(result, args.report)
    if args.json:
        print_json(result.to_dict())
    else:
        print(_report.text(result))
        if args.report:
            print(f"report: {args.report}/diagnosis.html")
    return 0
