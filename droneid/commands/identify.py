"""``droneid identify``: identify analytic models from logs and compare them with the empirical one."""
from __future__ import annotations

import argparse
import sys
import re
from dataclasses import replace

from droneid.core.lazy import lazy_module
from droneid.errors import ConfigError
from droneid.commands._common import ProgressBar, add_log_options, log_options, print_json, read_logs

_settings = lazy_module("droneid.planning.settings")      # the engine's parameters: numba
_identify = lazy_module("droneid.identify.pipeline")
_report = lazy_module("droneid.report.identify")


def add_budget_arguments(p: argparse.ArgumentParser, *, runs_help: str,
                         prune_default: str = "validation", paper: bool = False) -> None:
    """Options shared by identify, study and demo: data, prior, budget, parallelism. ``paper``:
    defaults of the paper's protocol (tilt-drag prior, its two targets, forward differences)."""
    p.add_argument("--target", default="vx_dot,vy_dot" if paper else None,
                   help="target(s), comma separated: vx_dot, vy_dot, vz_dot (default: every target the "
                        "prior models: vx_dot,vy_dot for tilt-drag, also vz_dot for rotor-thrust)")
    p.add_argument("--prior", default="tilt-drag" if paper else "auto",
                   help="physical model the search starts from: auto (default: rotor-thrust where the logs "
                        "have motor speeds, motor commands or thrust, tilt-drag otherwise), tilt-drag (the "
                        "paper), rotor-thrust, or FILE.toml:NAME")
    p.add_argument("--runs", type=int, default=None, help=runs_help)
    p.add_argument("--jobs", type=int, default=None, help="parallel worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, metavar="URL",
                   help="run on a Dask distributed cluster, e.g. tcp://host:8786, instead of local workers")
    p.add_argument("--generations", type=int, default=None, help="SNGP generations per run (paper: 60000)")
    p.add_argument("--population", type=int, default=None, help="SNGP population size (paper: 500)")
    p.add_argument("--seed", type=int, default=0, help="root seed; run seeds are spawned from it (default 0)")
    p.add_argument("--ts", type=float, default=0.05, help="sampling period of the data in s (default 0.05, the paper's)")
    p.add_argument("--method", default="forward" if paper else "central",
                   help="differentiator: central (default; no half-step lag), forward (the paper), savgol, spline")
    p.add_argument("--holdout", type=float, default=0.3 if paper else 0.0, metavar="FRACTION",
                   help="without --test: hold out the last FRACTION of each training flight as test data "
                        "(before any choice is made); " + ("default 0.3" if paper else
                        "default 0: train on everything and report validation (the same model as with --test)"))
    p.add_argument("--quick", action="store_true",
                   help="small budget for a fast look (3000 generations, population 200, 4 runs)")
    p.add_argument("--prune", default=prune_default, choices=("validation", "exact"),
                   help="validation: keep an evolved term only if it lowers the error on held-out "
                        "blocks of the training data (short equations); exact: the paper's engine, "
                        f"drop only dead terms (default {prune_default})")


#: the option a user typed for each IdentifyConfig parameter whose name differs from it
_FLAGS = {"test_fraction": "--holdout", "population_size": "--population", "targets": "--target"}


def config_from_args(args, **extra):
    """The IdentifyConfig of the parsed options; a refused value names the option as typed
    ("--holdout must be ...", not "The 'test_fraction' parameter must be ...")."""
    try:
        return _settings.IdentifyConfig.make(quick=args.quick, targets=args.target, prior=args.prior, runs=args.runs,
                                   jobs=args.jobs, scheduler=args.scheduler, generations=args.generations,
                                   population_size=args.population, seed=args.seed, ts=args.ts, method=args.method,
                                   test_fraction=args.holdout,
                                   prune=args.prune, **extra)
    except ConfigError as exc:
        text = re.sub(r"The '(\w+)' parameter(?: of \w+)? ",
                      lambda m: f"{_FLAGS.get(m.group(1), '--' + m.group(1).replace('_', '-'))} ", str(exc), count=1)
        raise ConfigError(text) from None


def register(sub) -> None:
    p = sub.add_parser(
        "identify",
        description="Identify an analytic model of each target from the training logs with SNGP "
                    "(prior features + formal constraints), compare it with the empirical model as given "
                    "and refit, and write a report. Defaults: --prior auto (rotor-thrust where the logs have "
                    "motor speeds, commands or thrust, else the paper's tilt-drag), 3 prior features, the "
                    "prior's constraints, 4 runs per target of at most 60000 generations x population 500 "
                    "(a run stops early once its validation error stops improving); --quick for a fast look.")
    p.add_argument("train", nargs="+", metavar="TRAIN_LOG", help="training log(s)")
    p.add_argument("--test", nargs="+", metavar="TEST_LOG", default=None,
                   help="test log(s): reported, never used for a choice (without them: see --holdout)")
    add_budget_arguments(p, runs_help="independent SNGP runs per target (default 4; the paper: 50; --quick: 4)")
    p.add_argument("--prior-features", type=int, default=3, choices=(0, 1, 3),
                   help="0: no prior; 1: the empirical model as one feature; 3: its three terms (default)")
    p.add_argument("--constraints", default="paper",
                   help="paper (default: the prior's own set), none, or a constraints TOML file")
    p.add_argument("--effects", default="auto", choices=("auto", "none"),
                   help="auto (default): diagnose the refit prior on the training flights and fold every "
                        "effect that passes into the prior; none: the paper's setting")
    p.add_argument("--delays", default="auto", choices=("auto", "none"),
                   help="auto (default): choose the input delay of the thrust signals by cross-validation "
                        "on the training flights; none: no delay")
    p.add_argument("--empirical", default="tilt-drag", metavar="PRIOR",
                   help="the empirical model every verdict compares with, as given: a prior name or "
                        "FILE.toml:NAME (default tilt-drag with --kD; v̇z = 0 where it has no model)")
    p.add_argument("--kD", dest="k_D", type=float, default=0.28, metavar="1/s",
                   help="the empirical model's drag constant k_D, when it has one (default 0.28 1/s)")
    p.add_argument("--rotation", default="auto", choices=("auto", "none"),
                   help="auto (default): where the logs have the attitude quaternion, body rates and per-motor "
                        "speeds (or per-motor commands: each rotor's speed from its command through the identified "
                        "motor model, torque inputs in units of full thrust), also model the body rates (ω̇x, ω̇y, "
                        "ω̇z), chosen by holding each training flight out in turn (at least two), and score the "
                        "whole vehicle open loop on the test flights; none: v̇ only")
    p.add_argument("--frame", default="auto", metavar="LAYOUT",
                   help="rotor layout of the rotational model: auto (default: identified from the training "
                        "flights' torque signs) or a layout of priors/torque.py, e.g. crazyflie_x, quad_x")
    p.add_argument("--report", default=None, metavar="DIR",
                   help="write result.json, report.md, report.html and PNG figures into DIR")
    p.add_argument("--json", action="store_true", help="print the result summary as one JSON line")
    add_log_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    cfg = config_from_args(args, prior_features=args.prior_features, constraints=args.constraints,
                           effects=args.effects, delays=args.delays, empirical=args.empirical, k_D=args.k_D,
                           rotation=args.rotation, frame=args.frame)
    train = read_logs(args.train, args)
    test = read_logs(args.test, args) if args.test else None
    bar = ProgressBar("SNGP runs", quiet=args.quiet or args.json)
    # predict reads its logs with the reader options recorded here by default
    result = replace(_identify.identify(train, test, cfg, progress=bar), reader_options=log_options(args))
    if args.report:
        _report.write(result, args.report)
    if args.json:
        print_json(_report.compact(result))
    else:
        print(_report.text(result))
        if args.report:
            print(f"\nreport written to {args.report}/ (result.json, report.html, report.md, figures)")
    if result.interrupted:
        print("droneid identify: interrupted; the finished runs are reported", file=sys.stderr)
        return 130
    return 0
