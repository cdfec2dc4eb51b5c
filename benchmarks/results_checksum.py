"""A checksum of the engine's results, to show a speed change left them bit for bit the same.

    .venv/bin/python benchmarks/results_checksum.py [--quick] [--json FILE]

Hashes (sha256 over JSON with floats written exactly, ``float.hex``):

- every variant of the paper-budget study (2 targets x 2 scenarios x 3 prior variants, 1 run each,
  60 000 generations, population 500, seed 0) on the simulated data of ``bench_study.py``: the
  equations, seeds, errors and p-values of ``study(...).to_dict()`` without its wall times;
- ``droneid fit``'s pipeline (:func:`droneid.engine.fit.fit_table`, the command's defaults) on the
  tables of ``bench_startup.py`` (160 and 1 000 samples; no prior, and the three tilt-drag terms
  as prior features): the fitted model (raw terms, coefficients, intercept), its generations and
  its training and test errors. The fits run their search threads side by side on ``--jobs``
  cores (default 2, as ``droneid fit`` on this machine kind); ``--jobs 1`` runs them one after the
  other and must print the same lines.

The simplified equation that ``droneid fit`` prints is not hashed: sympy simplifies it under a
wall-clock budget (``simplify_s``, 0.5 s), so how far it gets depends on the machine's load;
the model it simplifies is hashed. Run it before and after a change (e.g. in two git worktrees:
``cd WORKTREE && python benchmarks/results_checksum.py``: the script imports droneid from the
checkout it lives in) and compare the lines. ``--quick``: 3 000 generations instead of 60 000.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(1, str(ROOT / "benchmarks"))

TILT_DRAG = ("9.81*cos(yaw)*tan(pitch)/cos(roll)", "9.81*sin(yaw)*tan(roll)", "-0.28*vx")
_TIMING_KEYS = ("wall_s", "cpu_s")


def _exact(obj):
    """JSON-ready copy with every float as its exact hex form and timing keys dropped."""
    if isinstance(obj, dict):
        return {str(k): _exact(v) for k, v in obj.items() if str(k) not in _TIMING_KEYS}
    if isinstance(obj, (list, tuple)):
        return [_exact(v) for v in obj]
    if isinstance(obj, float):
        return obj.hex()
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):   # numpy scalars
        return _exact(obj.item())
    return obj


def digest(obj) -> str:
    return hashlib.sha256(json.dumps(_exact(obj), sort_keys=True).encode()).hexdigest()[:16]


def study_checksums(generations: int) -> dict[str, str]:
    from droneid.identify.pipeline import IdentifyConfig
    from droneid.simulation.simulator import simulate
    from droneid.identify.study import study

    train = simulate(path="eight", duration_s=8.0, seed=11).flight
    test = simulate(path="square", duration_s=12.55, seed=12).flight
    cfg = IdentifyConfig.make(targets=("vx_dot", "vy_dot"), runs=1, generations=generations,
                              population_size=500, seed=0, prune="exact")
    res = study([train], [test], cfg).to_dict()
    out = {}
    for target, t in res["targets"].items():
        for variant, v in t["variants"].items():    # "baseline/0" ... "constrained/3"
            out[f"study {target} {variant}"] = digest(v)
        out[f"study {target} empirical"] = digest({"as given": t["empirical"],
                                                  "refit": t["empirical_refit"]})
    return out


def fit_checksums(generations: int, jobs: int = 2) -> dict[str, str]:
    from bench_startup import write_tables
    from droneid.engine.fit import FitConfig, fit_table

    import tempfile
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tables = write_tables(Path(tmp))
        for n in (160, 1000):
            for label, priors in (("no prior", ()), ("3 priors", TILT_DRAG)):
                cfg = FitConfig(target="vx_dot", priors=priors, generations=generations, n_jobs=jobs)
                res = fit_table(tables[n], cfg, test=tables["test"])
                m = res.estimator
                out[f"fit {n} samples, {label}"] = digest({
                    "model": m.model_.to_dict(), "generations": m.generations_, "seed": m.seed_,
                    "rmse_train": res.rmse_train, "rmse_test": res.rmse_test})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 000 generations instead of 60 000")
    ap.add_argument("--json", default=None, help="also write the checksums to this JSON file")
    ap.add_argument("--jobs", type=int, default=2,
                    help="cores for the search threads of the fits (default 2; 1: one after the other)")
    args = ap.parse_args(argv)
    generations = 3000 if args.quick else 60000
    t0 = time.perf_counter()
    sums = {**fit_checksums(generations, args.jobs), **study_checksums(generations)}
    for k, v in sums.items():
        print(f"{v}  {k}")
    print(f"{digest(sums)}  ALL ({len(sums)} items, {generations} generations; "
          f"{time.perf_counter() - t0:.0f} s; droneid from {ROOT})")
    if args.json:
        Path(args.json).write_text(json.dumps(sums, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
