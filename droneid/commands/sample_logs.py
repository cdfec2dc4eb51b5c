"""``droneid sample-logs``: regenerate the shipped sample logs (byte-identical for the same code)."""
from __future__ import annotations

from droneid.core.lazy import lazy_module
from droneid.commands._common import ProgressBar

_samples = lazy_module("droneid.simulation.sample_logs")


def register(sub):
    p = sub.add_parser("sample-logs", description="Simulate and write every sample log defined in droneid/simulation/sample_logs.py, "
                                   "plus its README. The output is byte-identical on every run.")
    p.add_argument("--out", default="sample_logs", metavar="DIR", help="output folder (default sample_logs)")
    p.add_argument("--only", action="append", default=None, metavar="NAME",
                   help="write only this sample (repeatable; the README is then not rewritten)")
    p.set_defaults(func=run)


def run(args) -> int:
    paths = _samples.generate(args.out, names=args.only, progress=ProgressBar("sample-logs", quiet=args.quiet))
    if not args.quiet:
        for p in paths:
            print(p)
    return 0
