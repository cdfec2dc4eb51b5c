"""What a user waits for: ``droneid identify`` with its defaults on the five Crazyflie squares.

    .venv/bin/python benchmarks/bench_identify.py [--logs DIR] [--jobs N] [--repeats R] [--previous DIR]

Runs ``python -m droneid identify square_run1.csv ... square_run5.csv --json`` in a subprocess,
as a user runs it (interpreter start to exit, with Python's bytecode cache), in two variants side
by side: with ``--rotation none`` (the three v̇ targets; issue 26: <= 10 s wall on 2 cores) and
with the defaults (six targets: v̇ and the rotational choice of ω̇x, ω̇y, ω̇z; issue 26: <= 20 s,
issue 28: <= 30 s), whatever identify is in this checkout. Each figure is the median of R runs
taken round-robin (default 3), so that load from other processes spreads over all of them. It
prints each variant's wall time, the CPU time of the command and its workers, the machine's
load, per target the generations the runs used, and the ratio of the two variants.

``--previous DIR`` also times the same commands from another checkout (e.g. a git worktree of an
earlier commit), interleaved run by run with this one, so that both see the same machine: the
``before`` figures and the ratio now/before. On a shared machine wall time varies by tens of per
cent from minute to minute; the interleaved ratio is the figure to judge a change by.

Skipped with the reason when ../shared/real_logs/mocap/crazyflie_nanodrone (beside the repo) is
absent.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOGS = ROOT.parent / "shared" / "real_logs" / "mocap" / "crazyflie_nanodrone"
SQUARES = [f"square_run{i}.csv" for i in range(1, 6)]
#: (label, extra arguments, wall-time target in s on 2 cores)
VARIANTS = (("three v̇ targets (--rotation none)", ["--rotation", "none"], 10.0),
            ("six targets (defaults: v̇ and rotation)", [], 20.0))


#: the environment of the timed processes: a user's Python writes and reads its bytecode cache
#: (PYTHONDONTWRITEBYTECODE would have modules compiled from source at every run)
_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def run(logs: Path, jobs: int | None = None, extra: list[str] | None = None, root: Path = ROOT) -> dict:
    """Time one ``droneid identify`` on the squares from the checkout ``root``; returns the
    figures (no printing)."""
    cmd = [sys.executable, "-m", "droneid", "--quiet", "identify", *[str(logs / s) for s in SQUARES],
           "--json", *(extra or [])]
    if jobs:
        cmd += ["--jobs", str(jobs)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=root, capture_output=True, text=True, env=_ENV)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"droneid identify exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    res = json.loads(proc.stdout)
    targets = {}
    for name, tr in res.get("targets", {}).items():
        gens = [r["generations"] for r in tr.get("runs", []) if r]
        targets[name] = {"runs": len(gens), "generations_median": statistics.median(gens) if gens else 0,
                         "generations_min": min(gens, default=0), "generations_max": max(gens, default=0),
                         "run_wall_s_median": statistics.median(r["wall_s"] for r in tr["runs"] if r)}
    rot = res.get("rotation") or {}
    for a in rot.get("axes", []):
        targets[a["target"]] = {"rung": a["rung"]}
    return {"wall_s": wall, "cpu_s": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
            "load_before": load0, "load_after": os.getloadavg()[0], "targets": targets,
            "command": " ".join(cmd[1:])}


def _walls(runs) -> str:
    return ", ".join(f"{r['wall_s']:.1f}" for r in runs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=Path, default=LOGS, help="folder holding square_run1..5.csv")
    ap.add_argument("--jobs", type=int, default=None, help="workers (default: identify's default)")
    ap.add_argument("--repeats", type=int, default=3, help="runs per figure, round-robin (default 3)")
    ap.add_argument("--previous", type=Path, default=None,
                    help="another checkout to time interleaved with this one (the 'before' figures)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    missing = [s for s in SQUARES if not (args.logs / s).is_file()]
    if missing:
        print(f"skipped: {args.logs / missing[0]} is absent (the shared real logs live beside the "
              "repo, not in it)")
        return 0
    roots = [ROOT] + ([args.previous.resolve()] if args.previous else [])
    for root in roots:      # a first run per checkout writes its bytecode and numba caches
        run(args.logs, args.jobs, ["--rotation", "none", "--generations", "100"], root)
    got = {(label, root): [] for label, _, _ in VARIANTS for root in roots}
    for _ in range(args.repeats):
        for label, extra, _ in VARIANTS:
            for root in roots:
                got[label, root].append(run(args.logs, args.jobs, extra, root))
    walls = []
    for label, _, target in VARIANTS:
        runs = got[label, ROOT]
        wall = statistics.median(r["wall_s"] for r in runs)
        cpu = statistics.median(r["cpu_s"] for r in runs)
        walls.append(wall)
        r = runs[0]
        print(f"== {label}\n$ python {r['command']}")
        print(f"wall {wall:.1f} s (median of {len(runs)}: {_walls(runs)}), "
              f"CPU {cpu:.1f} s (command + workers), {os.cpu_count()} cores, load average "
              f"{min(x['load_before'] for x in runs):.2f}-{max(x['load_after'] for x in runs):.2f}")
        if args.previous:
            before = got[label, roots[1]]
            bwall = statistics.median(x["wall_s"] for x in before)
            bcpu = statistics.median(x["cpu_s"] for x in before)
            print(f"before ({args.previous}, interleaved): wall {bwall:.1f} s "
                  f"({_walls(before)}), CPU {bcpu:.1f} s; "
                  f"now / before: wall {wall / bwall:.2f}x, CPU {cpu / bcpu:.2f}x")
        for name, t in r["targets"].items():
            if "rung" in t:
                print(f"  {name}: rotational rung {t['rung']}")
                continue
            print(f"  {name}: {t['runs']} runs, generations median {t['generations_median']:.0f} "
                  f"(min {t['generations_min']}, max {t['generations_max']}) of the budget, "
                  f"median run {t['run_wall_s_median']:.1f} s")
        verdict = "met" if wall <= target else "NOT met"
        print(f"target <= {target:.0f} s wall on 2 cores: {verdict}"
              + (" (machine loaded: compare the CPU time / 2)" if r["load_before"] > 1.5 else ""))
    print(f"\nsix targets / three targets: {walls[1] / walls[0]:.2f}x wall")
    return 0


if __name__ == "__main__":
    sys.exit(main())
