"""``droneid demo`` (``make demo``): the paper's drone experiment, then droneid's loop, on the shipped sample logs.

Trains on the eight-shaped flight, tests on the square flight (as the paper's Bebop 2 experiment),
identifies v̇x and v̇y in the paper's setting (tilt-drag's 3 terms as prior features, the paper's
constraints, forward differences, no effects), prints the equations and the ladder and writes the
report. Then identify with its defaults on the flight that logs motor speeds: it picks the
rotor-thrust prior, finds the planted 40 ms thrust delay on the training flight alone and models
v̇z too. Last it closes the loop on the sample flight with wind and quadratic drag: the diagnosis
traces the residual to the effects it lacks and reports the error before and after. The budget is
cut so the whole demo takes about a minute on 2 cores; ``droneid identify`` runs the full budget.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from droneid.errors import DataError
from droneid.core.lazy import lazy_module
from droneid.commands._common import ProgressBar, read_logs

_settings = lazy_module("droneid.planning.settings")
_identify = lazy_module("droneid.identify.pipeline")
_report = lazy_module("droneid.report.identify")
_diagnose = lazy_module("droneid.diagnosis.diagnose")
_diagnose_report = lazy_module("droneid.report.diagnose")

#: about a minute on a 2-core machine (measured: `make demo` prints its wall time)
DEMO_BUDGET = {"runs": 8, "generations": 6000, "population_size": 300}
_FORMATS = (".tlog", ".csv", ".mcap", ".bin", ".ulg")


def find_sample_logs(folder: Path | None = None) -> tuple[Path, Path]:
    """(train eight log, test square log) from sample_logs/, preferring one format for both."""
    candidates = [folder] if folder else [Path.cwd() / "sample_logs",
                                          Path(__file__).resolve().parents[2] / "sample_logs"]
    for d in candidates:
        if not d.is_dir():
            continue
        for ext in _FORMATS:
            eight = sorted(d.glob(f"*train*eight*{ext}")) or sorted(d.glob(f"*eight*{ext}"))
            square = sorted(d.glob(f"*test*square*{ext}")) or sorted(d.glob(f"*square*{ext}"))
            if eight and square:
                return eight[0], square[0]
    raise DataError("the sample logs (sample_logs/*eight*, *square*) are missing; "
                    "run `make sample-logs` to create them")


def register(sub) -> None:
    p = sub.add_parser("demo", description=__doc__.split("\n\n")[1])
    p.add_argument("--out", default="out/demo_report", metavar="DIR", help="report folder (default out/demo_report)")
    p.add_argument("--jobs", type=int, default=None, help="parallel workers (default: all cores)")
    p.add_argument("--runs", type=int, default=DEMO_BUDGET["runs"], help=f"SNGP runs per target (default {DEMO_BUDGET['runs']})")
    p.add_argument("--generations", type=int, default=DEMO_BUDGET["generations"],
                   help=f"generations per run (default {DEMO_BUDGET['generations']}; the paper: 60000)")
    p.add_argument("--population", type=int, default=DEMO_BUDGET["population_size"],
                   help=f"population (default {DEMO_BUDGET['population_size']}; the paper: 500)")
    p.add_argument("--logs", "--dir", dest="logs", default=None, metavar="DIR",
                   help="folder of the sample logs (default sample_logs/)")
    p.set_defaults(func=run)


def run(args) -> int:
    t0 = time.perf_counter()
    train_path, test_path = find_sample_logs(Path(args.logs) if args.logs else None)
    print(f"droneid demo: train on {train_path.name} (eight), test on {test_path.name} (square); "
          f"3 prior features (tilt-drag terms) + the paper's constraints; {args.runs} runs x "
          f"{args.generations} generations, population {args.population} (the paper: 50 x 60000 x 500)\n")
    cfg = _settings.IdentifyConfig.make(targets=("vx_dot", "vy_dot"), prior="tilt-drag", prior_features=3,
                              constraints="paper", runs=args.runs, generations=args.generations,
                              population_size=args.population, jobs=args.jobs, seed=0, method="forward",
                              effects="none", delays="none")
    train, test = read_logs([train_path]), read_logs([test_path])
    result = _identify.identify(train, test, cfg, progress=ProgressBar("SNGP runs", quiet=args.quiet)).to_dict()
    _report.write(result, args.out)
    print(_report.text(result))
    print("\nThe sample flights are simulated with the tilt-drag model itself (k_D = 0.28) plus mocap-like "
          "noise and no undeclared effect, so the best an identified model can do here is match the "
          "refit empirical model; priors and constraints keep it there (β ≈ 1 on the prior "
          "features, e_c near 0).")
    rotor_log = train_path.parent / f"rotor_climb_eight{train_path.suffix}"
    if rotor_log.is_file():
        print(f"\n== the loop on a log with motor speeds: {rotor_log.name} (simulated with a rotor model: "
              "thrust = k_f Σ rpm², motor lag 20 ms, speeds logged 40 ms ahead of the thrust; identify's "
              "defaults: --prior auto, thrust delay and effects chosen on this flight alone)\n")
        rcfg = _settings.IdentifyConfig.make(runs=max(1, args.runs // 2), generations=args.generations,
                                   population_size=args.population, jobs=args.jobs, seed=0)
        rres = _identify.identify(read_logs([rotor_log]), None, rcfg,
                        progress=ProgressBar("SNGP runs", quiet=args.quiet)).to_dict()
        _report.write(rres, Path(args.out) / "rotor")
        print(_report.text(rres))
        print(f"rotor report: {args.out}/rotor/report.html")
    effect_log = train_path.parent / f"wind_quadratic_eight{train_path.suffix}"
    if effect_log.is_file():
        print(f"\n== closing the loop on {effect_log.name} (planted: wind (1.5, -1) m/s and quadratic "
              "drag c_D/m = 0.15 1/m, neither in the tilt-drag model)\n")
        diag = _diagnose.diagnose(read_logs([effect_log]), None, prior="tilt-drag", targets=("vx_dot", "vy_dot"),
                        progress=ProgressBar("diagnose", quiet=args.quiet))
        _diagnose_report.write(diag, Path(args.out) / "diagnosis")
        print(_diagnose_report.text(diag))
        print(f"diagnosis report: {args.out}/diagnosis/diagnosis.html")
    print(f"\nreport: {args.out}/report.html (also report.md, result.json, PNG figures); "
          f"demo wall time {time.perf_counter() - t0:.0f} s")
    if result["interrupted"]:
        print("droneid demo: interrupted; the finished runs are reported", file=sys.stderr)
        return 130
    return 0
