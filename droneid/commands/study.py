"""``droneid study``: the paper's comparison (Tables II-III) of prior variants and constraints."""
from __future__ import annotations

import sys

from droneid.core.lazy import lazy_module
from droneid.commands._common import ProgressBar, add_log_options, print_json, read_logs
from droneid.commands.identify import add_budget_arguments, config_from_args

_study = lazy_module("droneid.identify.study")
_report = lazy_module("droneid.report.study")


def register(sub) -> None:
    p = sub.add_parser(
        "study",
        description="Run the paper's protocol on your data: scenarios baseline and constrained x prior "
                    "features none/1/3 x R runs per target; prints and saves the median test errors and "
                    "Wilcoxon rank-sum p-values of each prior variant against no prior.")
    p.add_argument("train", nargs="+", metavar="TRAIN_LOG", help="training log(s)")
    p.add_argument("--test", nargs="+", metavar="TEST_LOG", default=None,
                   help="test log(s); without them the last 30%% of the training data are held out")
    add_budget_arguments(p, paper=True, runs_help="runs per target, scenario and prior variant (default 10; paper: 50)",
                         prune_default="exact")  # the paper's protocol
    p.add_argument("--constraints", default="paper",
                   help="constraints of the constrained scenario: paper or a constraints TOML file "
                        "(default paper)")
    p.add_argument("--out", default="study", metavar="DIR",
                   help="write study.json, study.md, study.html and figures here (default ./study)")
    p.add_argument("--json", action="store_true",
                   help="print the study result as one JSON line (no budget line, no progress)")
    add_log_options(p)
    p.set_defaults(func=run)


def budget_line(cfg) -> str:
    """The study's whole budget in one line, said before it starts (a full study takes minutes)."""
    SCENARIOS, PRIOR_VARIANTS = _study.SCENARIOS, _study.PRIOR_VARIANTS
    n = len(cfg.targets) * len(SCENARIOS) * len(PRIOR_VARIANTS) * cfg.runs
    line = (f"study: {n} SNGP runs ({len(cfg.targets)} target(s) x {len(SCENARIOS)} scenarios x "
            f"{len(PRIOR_VARIANTS)} prior variants x {cfg.runs} runs), each {cfg.generations} "
            f"generations x population {cfg.population_size}")
    if not cfg.quick:
        line += " (--runs sets only the run count; --quick: 3000 generations x population 200)"
    return line


def run(args) -> int:
    if args.runs is None and not args.quick:
        args.runs = 10  # the study's own default (identify's is 4)
    cfg = config_from_args(args, constraints=args.constraints)
    if not (args.quiet or args.json):
        print(budget_line(cfg), file=sys.stderr)
    train = read_logs(args.train, args)
    test = read_logs(args.test, args) if args.test else None
    bar = ProgressBar("SNGP runs", quiet=args.quiet or args.json)
    result = _study.study(train, test, cfg, progress=bar)
    _report.write(result, args.out)
    if args.json:
        print_json(result.to_dict())
    else:
        print(_report.text(result))
        print(f"\nstudy written to {args.out}/ (study.json, study.md, study.html)")
    if result.interrupted:
        print("droneid study: interrupted; the finished runs are reported", file=sys.stderr)
        return 130
    return 0
