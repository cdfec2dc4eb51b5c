"""How identify's cost grows with the data (issue 38): ``droneid identify`` with its defaults on 5,
10, 20 and 40 flights (the five Crazyflie squares repeated under distinct names in a temporary
folder), whole processes as a user runs them.

    .venv/bin/python benchmarks/bench_scaling.py [--flights 5,10,20,40] [--rotation auto|none]
        [--quick] [--stages] [--logs DIR] [--json FILE]

Per flight count: the wall time, the CPU time of the command and its workers, and the peak
memory (the largest process's maximum resident set, from ``/usr/bin/time -f``), each with its
ratio to 5 flights (target of issue 38: the cost at 40 flights at most 9x the cost at 5, 8x the
data). ``--quick`` runs 5 and 10 flights with identify's ``--quick`` budget. ``--stages`` instead
times identify's stages in this process (reading, the plan: thrust offset and diagnosis, the
targets' datasets, the runs with the rotational job beside them, the summaries: guards, ladder,
intervals, constancy; and the rotational choice alone), with ``--rotation`` auto and none; its CPU
figures include the forked workers'. The squares are copies (the shared logs are never written);
the repeated flights are the same data, so the choices stay those of the squares.

Skipped with the reason when ../shared/real_logs/mocap/crazyflie_nanodrone (beside the repo) is
absent.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOGS = ROOT.parent / "shared" / "real_logs" / "mocap" / "crazyflie_nanodrone"
SQUARES = [f"square_run{i}.csv" for i in range(1, 6)]
TARGET_RATIO = 9.0 / 8.0    # issue 38: cost at 40 flights <= 9x the cost at 5 (8x the data): 1.125x linear
_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def flight_files(logs: Path, n: int, folder: Path) -> list[Path]:
    """``n`` flights in ``folder``: the squares in turn, copy c of square i named
    ``square_run{i}_c{c}.csv`` (each copy its own flight)."""
    out = []
    for j in range(n):
        src = logs / SQUARES[j % len(SQUARES)]
        dst = folder / f"{src.stem}_c{j // len(SQUARES)}.csv"
        if not dst.exists():
            shutil.copyfile(src, dst)
        out.append(dst)
    return out


def run(files: list[Path], extra: list[str]) -> dict:
    """One ``droneid identify`` process on ``files``: wall s, CPU s (with workers), peak RSS MB."""
    cmd = [sys.executable, "-m", "droneid", "--quiet", "identify", *map(str, files), "--json", *extra]
    timer = shutil.which("time") or "/usr/bin/time"
    with tempfile.NamedTemporaryFile("r", suffix=".time") as tf:
        full = [timer, "-f", "%e %U %S %M", "-o", tf.name, *cmd] if os.path.exists(timer) else cmd
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run(full, cwd=ROOT, capture_output=True, text=True, env=_ENV)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        fields = tf.read().split()
    if proc.returncode != 0:
        raise RuntimeError(f"droneid identify exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    res = json.loads(proc.stdout)
    rot = res.get("rotation") or {}
    return {"flights": len(files), "wall_s": wall,
            "cpu_s": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
            "peak_mb": float(fields[-1]) / 1024.0 if fields else float("nan"),
            "rungs": [a["rung"] for a in rot.get("axes", [])], "load": os.getloadavg()[0]}


def stages(files: list[Path], rotation: str, quick: bool) -> dict[str, tuple[float, float]]:
    """{stage: (wall s, CPU s with forked workers)} of one identify in this process."""
    import droneid.identify.pipeline as ident
    return _stages(ident, files, rotation, quick)


def _clock():
    ru = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.perf_counter(), sum(r.ru_utime + r.ru_stime for r in ru)


def _stages(ident, files, rotation, quick):
    from parsers import read_flight
    from droneid.rotation.stage import choose_rotation
    spent: dict[str, list[float]] = {}

    def timed(name, fn):
        def wrapper(*a, **kw):
            w0, c0 = _clock()
            try:
                return fn(*a, **kw)
            finally:
                w1, c1 = _clock()
                acc = spent.setdefault(name, [0.0, 0.0])
                acc[0] += w1 - w0
                acc[1] += c1 - c0
        return wrapper

    w0, c0 = _clock()
    flights = [read_flight(str(f)) for f in files]
    w1, c1 = _clock()
    spent["reading the logs"] = [w1 - w0, c1 - c0]
    names = {"plan_identification": "plan: thrust offset, diagnosis", "prepare_target": "targets' datasets",
             "compile_once": "engine kernels (cache load)",
             "summarise_target": "summaries: guards, ladder, intervals, constancy"}
    saved = {n: getattr(ident, n) for n in names}
    saved_run = ident.runner.run_jobs
    try:
        for n, label in names.items():
            setattr(ident, n, timed(label, saved[n]))
        ident.runner.run_jobs = timed("SNGP runs" + (" + rotational job beside them" if rotation != "none" else ""),
                                      saved_run)
        cfg = ident.IdentifyConfig.make(rotation=rotation, **({"runs": 4, "generations": 3000,
                                                                "population_size": 200} if quick else {}))
        w0, c0 = _clock()
        ident.identify(flights, None, cfg)
        w1, c1 = _clock()
    finally:
        for n in names:
            setattr(ident, n, saved[n])
        ident.runner.run_jobs = saved_run
    spent["identify in all"] = [w1 - w0, c1 - c0]
    if rotation != "none":
        w0, c0 = _clock()
        choose_rotation(flights)
        w1, c1 = _clock()
        spent["the rotational choice alone (choose_rotation, one core)"] = [w1 - w0, c1 - c0]
    return {k: (v[0], v[1]) for k, v in spent.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", default=None, help="flight counts, comma-separated (default 5,10,20,40)")
    ap.add_argument("--rotation", default="auto", choices=("auto", "none"), help="identify's --rotation")
    ap.add_argument("--quick", action="store_true", help="5 and 10 flights, identify --quick")
    ap.add_argument("--stages", action="store_true", help="time identify's stages in this process instead")
    ap.add_argument("--logs", type=Path, default=LOGS, help="folder holding square_run1..5.csv")
    ap.add_argument("--json", type=Path, default=None, help="write the figures to this file")
    args = ap.parse_args(argv)
    counts = [int(x) for x in (args.flights or ("5,10" if args.quick else "5,10,20,40")).split(",")]
    if any(c < 2 for c in counts):
        ap.error("--flights: every count must be at least 2")
    missing = [s for s in SQUARES if not (args.logs / s).is_file()]
    if missing:
        print(f"skipped: {args.logs / missing[0]} is absent (the shared real logs live beside the repo, not in it)")
        return 0
    extra = ["--rotation", args.rotation] + (["--quick"] if args.quick else [])
    out = []
    with tempfile.TemporaryDirectory(prefix="droneid-scaling-") as tmp:
        folder = Path(tmp)
        if args.stages:
            for n in counts:
                for rot in ("auto", "none"):
                    got = stages(flight_files(args.logs, n, folder), rot, args.quick)
                    print(f"== {n} flights, --rotation {rot}{' --quick' if args.quick else ''}: "
                          f"stage, wall s, CPU s (with workers)")
                    for k, (w, c) in got.items():
                        print(f"  {k:<58} {w:8.2f} {c:8.2f}")
                    out.append({"flights": n, "rotation": rot, "stages": got})
        else:
            run(flight_files(args.logs, 2, folder), extra + ["--generations", "100"])   # caches warm
            for n in counts:
                r = run(flight_files(args.logs, n, folder), extra)
                out.append(r)
                print(f"{n:3d} flights: wall {r['wall_s']:7.1f} s, CPU {r['cpu_s']:7.1f} s, peak "
                      f"{r['peak_mb']:6.0f} MB, rotation {'/'.join(r['rungs']) or '-'}, load {r['load']:.1f}",
                      flush=True)
            base = out[0]
            print(f"\nflights   wall s  ratio   CPU s  ratio  peak MB  ratio   (ratios to {base['flights']} flights)")
            for r in out:
                print(f"{r['flights']:7d} {r['wall_s']:8.1f} {r['wall_s'] / base['wall_s']:6.2f} "
                      f"{r['cpu_s']:7.1f} {r['cpu_s'] / base['cpu_s']:6.2f} {r['peak_mb']:8.0f} "
                      f"{r['peak_mb'] / base['peak_mb']:6.2f}")
            top = out[-1]
            if top["flights"] >= 8 * base["flights"]:
                ratio = top["cpu_s"] / base["cpu_s"]
                data = top["flights"] / base["flights"]
                print(f"target (issue 38): CPU at {top['flights']} flights <= {TARGET_RATIO * data:g}x at "
                      f"{base['flights']} ({data:g}x the data, 9x at 8x): {ratio:.2f}x, "
                      f"{'met' if ratio <= TARGET_RATIO * data else 'NOT met'}")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
