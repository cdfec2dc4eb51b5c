"""Speed of the SNGP engine at the paper's budget, against the authors' Java SNGP.

    .venv/bin/python benchmarks/bench_sngp.py [--repeats R] [--quick] [--previous DIR]

Paper budget (Table I): population 500, 60 000 generations, nf 10, depth 7, function set
{+, -, x, square, cube, sin, cos}, early stopping off (the paper's fixed budget). Data:
drone-like samples along an eight (tilt-drag model with a planted quadratic drag -0.3|vx|vx the
model lacks, noise 0.05 m/s^2), test set on a different path. Prints, side by side: droneid's
CPU time per run, the engine's previous figures (the README's, or measured in this run from
another checkout with ``--previous DIR``), the authors' SNGP.jar measured in this run when Java
and the jar are available (``SNGP_JAR=path/to/SNGP.jar`` and ``SNGP_JAR_CMD``, a command template
with ``{jar}``, ``{train_csv}`` and ``{generations}``), otherwise skipped with the reason and the
jar's figures measured earlier on this machine (22 s on 160 samples, 155 s on 1 000), labelled
as such. Then generations/s, node evaluations/s, scaling, early stopping (generations used, time
and errors with and without it) and test errors (noise floor 0.05) to show accuracy is kept.
One core: the search is single-threaded. Other processes on a shared machine inflate wall time;
CPU time (process_time) is the fairer figure then.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(os.environ.get("BENCH_SNGP_ROOT") or Path(__file__).resolve().parents[1])
sys.path.insert(0, str(ROOT))

from droneid.sngp import SNGPRegressor  # noqa: E402

NAMES = ["vx", "pitch", "roll", "yaw"]
#: SNGP.jar at the paper budget, measured earlier on this 2-core machine (README)
REFERENCE_S = {160: 22.0, 1000: 155.0}
#: this engine before issue 16 (README: whole fit CPU s, search CPU s; loaded machine)
PREVIOUS_S = {160: (2.20, 1.62), 1000: (6.73, 6.15)}
#: done-when of issue 16: speed-up over SNGP.jar at the paper budget
TARGET_X = {160: 20.0, 1000: 40.0}
NOISE = 0.05


def drone_data(n, seed, path="eight"):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 40, n)
    if path == "eight":
        vx = 1.5 * np.sin(0.5 * t) + 0.1 * rng.normal(size=n)
        pitch = 0.2 * np.sin(0.5 * t + 0.4)
        roll = 0.15 * np.sin(1.0 * t)
        yaw = 0.6 * np.sin(0.2 * t) + 0.2
    else:  # "square": piecewise straight legs
        leg = (t // 10).astype(int) % 4
        vx = np.where(leg % 2 == 0, 1.2, -0.8) * np.sin(np.pi * (t % 10) / 10)
        pitch = 0.18 * np.cos(np.pi * (t % 10) / 10) * np.where(leg < 2, 1, -1)
        roll = 0.1 * np.sin(0.7 * t)
        yaw = 0.3 * leg - 0.4
    g, kd = 9.81, 0.28
    y = (g * np.cos(yaw) * np.tan(pitch) / np.cos(roll) + g * np.sin(yaw) * np.tan(roll)
         - kd * vx - 0.3 * np.abs(vx) * vx + NOISE * rng.normal(size=n))
    return np.c_[vx, pitch, roll, yaw], y


def one_run(n, generations, seed, X_test, y_test):
    X, y = drone_data(n, seed=100 + n)
    kw = {"early_stop_window": None} if "early_stop_window" in SNGPRegressor().get_params() else {}
    est = SNGPRegressor(generations=generations, seed=seed, **kw)   # paper budget, fixed
    c0, w0 = time.process_time(), time.perf_counter()
    est.fit(X, y, feature_names=NAMES)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    s = est.search_stats_
    return {"n": n, "gens": generations, "wall": wall, "cpu": cpu, "search_cpu": s["search_cpu_s"],
            "gps": s["generations"] / s["search_cpu_s"],
            "eps": s["node_evaluations"] / s["search_cpu_s"],
            "evals_per_gen": s["node_evaluations"] / s["generations"],
            "train": est.rmse_train_, "test": est.rmse(X_test, y_test)}


def median_run(n, generations, repeats, X_test, y_test):
    runs = [one_run(n, generations, seed, X_test, y_test) for seed in range(1, repeats + 1)]
    return {k: (statistics.median(r[k] for r in runs) if isinstance(runs[0][k], float) else runs[0][k])
            for k in runs[0]}


def jar_status() -> tuple[bool, str]:
    """Whether SNGP.jar can be run here, and why not."""
    if shutil.which("java") is None:
        return False, "no java on PATH"
    jar = os.environ.get("SNGP_JAR")
    if not jar or not Path(jar).is_file():
        return False, "SNGP_JAR does not name the authors' SNGP.jar"
    if not os.environ.get("SNGP_JAR_CMD"):
        return False, "SNGP_JAR_CMD (the command template that runs the jar) is not set"
    return True, ""


def jar_run(n: int, generations: int) -> dict:
    """One SNGP.jar run on the same training data (CPU time of the Java process; its training
    RMSE when its output has a line like ``rmse_train = x``)."""
    X, y = drone_data(n, seed=100 + n)
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "train.csv"
        np.savetxt(csv, np.c_[X, y], delimiter=",", header=",".join(NAMES + ["y"]), comments="")
        cmd = os.environ["SNGP_JAR_CMD"].format(jar=os.environ["SNGP_JAR"], train_csv=csv,
                                                generations=generations)
        import resource
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        out = subprocess.run(cmd, shell=True, capture_output=True, text=True, check=True).stdout
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    m = re.search(r"rmse[_ ]?train\D{0,5}([0-9.eE+-]+)", out, re.IGNORECASE)
    return {"cpu": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
            "train": float(m.group(1)) if m else float("nan")}


def previous_run(root: str, n: int, repeats: int) -> dict:
    """The same paper-budget measurement with the engine of another checkout (``--previous``),
    in a subprocess so that its droneid is the one imported."""
    env = dict(os.environ, BENCH_SNGP_ROOT=str(Path(root).resolve()))
    out = subprocess.run([sys.executable, __file__, "--worker", str(n), "--repeats", str(repeats)],
                         env=env, capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def early_stop_table(sizes, seeds=3):
    """Generations, time and errors of the estimator's default early stopping vs the fixed
    budget (3 prior features, the same seeds)."""
    priors = ["9.81*cos(yaw)*tan(pitch)/cos(roll)", "9.81*sin(yaw)*tan(roll)", "-0.28*vx"]
    Xt, yt = drone_data(251, seed=7, path="square")
    print(f"\n## Early stopping (default window {SNGPRegressor().early_stop_window} generations, margin "
          f"{SNGPRegressor().early_stop_margin:g}) vs the fixed budget; 3 prior features, "
          f"median of {seeds} seeds")
    print(f"{'samples':>7} {'prune':>10} {'setting':>8} {'generations':>11} {'cpu s':>6} {'rmse train':>10} "
          f"{'rmse test':>9}")
    for n in sizes:
        X, y = drone_data(n, seed=100 + n)
        for prune in ("exact", "validation"):
            for label, w in (("fixed", None), ("early", SNGPRegressor().early_stop_window)):
                rows = []
                for seed in range(1, seeds + 1):
                    c0 = time.process_time()
                    m = SNGPRegressor(seed=seed, prune=prune, early_stop_window=w, simplify_s=0).fit(
                        X, y, feature_names=NAMES, priors=priors)
                    rows.append((m.generations_, time.process_time() - c0, m.rmse_train_, m.rmse(Xt, yt)))
                med = [statistics.median(r[i] for r in rows) for i in range(4)]
                print(f"{n:>7} {prune:>10} {label:>8} {med[0]:11.0f} {med[1]:6.2f} {med[2]:10.4f} {med[3]:9.4f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1, help="runs per setting (median reported)")
    ap.add_argument("--quick", action="store_true", help="only the two headline runs")
    ap.add_argument("--seeds", type=int, default=5, help="runs per setting in the accuracy table")
    ap.add_argument("--previous", default=None,
                    help="a checkout of the previous engine to time side by side (e.g. a git worktree of main)")
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    X_test, y_test = drone_data(251, seed=7, path="square")
    if args.worker:
        SNGPRegressor(generations=200, seed=0, simplify_s=0).fit(*drone_data(50, 0), feature_names=NAMES)
        print(json.dumps(median_run(args.worker, 60000, args.repeats, X_test, y_test)))
        return 0

    print(f"# SNGP benchmark: {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} (other processes share "
          "the machine: wall time is inflated, CPU time is the fairer figure)")
    t = time.perf_counter()
    SNGPRegressor(generations=200, seed=0, simplify_s=0).fit(*drone_data(50, 0), feature_names=NAMES)
    print(f"# warm-up (numba compile or cache load): {time.perf_counter() - t:.1f} s")
    jar_ok, jar_why = jar_status()
    print("# SNGP.jar: measured in this run" if jar_ok else
          f"# SNGP.jar: skipped ({jar_why}); its column shows the jar's CPU time measured earlier on "
          "this machine (README), marked 'ref'")

    print("\n## Paper budget, side by side (population 500, 60 000 generations, nf 10, depth 7, Table I "
          "set, fixed budget)")
    prev_label = "prev (this run)" if args.previous else "prev (README)"
    head = (f"{'samples':>7} {'cpu s':>7} {'search':>7} {prev_label:>15} {'jar s':>9} {'vs jar':>7} "
            f"{'target':>6} {'vs prev':>7} {'gen/s':>8} {'evals/gen':>9} {'train':>7} {'jar train':>9} "
            f"{'prev train':>10} {'test':>7}")
    print(head)
    rows = {}
    sizes = (160, 1000) if args.quick else (160, 500, 1000)
    for n in sizes:
        r = median_run(n, 60000, args.repeats, X_test, y_test)
        rows[n] = r
        if args.previous:
            pr = previous_run(args.previous, n, args.repeats)
            prev_cpu, prev_train = pr["cpu"], pr["train"]
        else:
            prev_cpu, prev_train = (PREVIOUS_S[n][0] if n in PREVIOUS_S else float("nan")), float("nan")
        if jar_ok:
            jr = jar_run(n, 60000)
            jar_s, jar_train, jar_tag = jr["cpu"], jr["train"], ""
        else:
            jar_s, jar_train, jar_tag = REFERENCE_S.get(n, float("nan")), float("nan"), " ref"
        vs_jar = jar_s / r["cpu"]
        target = TARGET_X.get(n)
        print(f"{n:>7} {r['cpu']:7.2f} {r['search_cpu']:7.2f} {prev_cpu:15.2f} {jar_s:5.1f}{jar_tag:<4} "
              f"{vs_jar:6.1f}x {(f'{target:.0f}x' if target else ''):>6} {prev_cpu / r['cpu']:6.2f}x "
              f"{r['gps']:8.0f} {r['evals_per_gen']:9.1f} {r['train']:7.4f} {jar_train:9.4f} {prev_train:10.4f} "
              f"{r['test']:7.4f}")
    print("(cpu s: the whole fit incl. pruning and sympy, the figure the ratios use; search: the SNGP\n"
          " search alone; rates per CPU second of search. 'ref': not measured in this run. README\n"
          " figures of the previous engine were taken on a loaded machine: --previous measures it here.)")

    if not args.quick:
        print("\n## Scaling with generations (160 samples)")
        print(f"{'generations':>11} {'cpu s':>7} {'search':>7} {'ratio':>6} {'gens ratio':>10}")
        base = None
        for g in (15000, 30000, 60000):
            r = rows[160] if g == 60000 else median_run(160, g, args.repeats, X_test, y_test)
            base = base or r
            print(f"{g:>11} {r['cpu']:7.2f} {r['search_cpu']:7.2f} "
                  f"{r['search_cpu'] / base['search_cpu']:6.2f} {g / base['gens']:10.2f}")
        print("\n## Scaling with samples (60 000 generations)")
        print(f"{'samples':>7} {'cpu s':>7} {'search':>7} {'ratio':>6} {'samples ratio':>13} {'us/gen':>7}")
        for n in sizes:
            r = rows[n]
            print(f"{n:>7} {r['cpu']:7.2f} {r['search_cpu']:7.2f} "
                  f"{r['search_cpu'] / rows[160]['search_cpu']:6.2f} {n / 160:13.2f} "
                  f"{1e6 * r['search_cpu'] / 60000:7.1f}")
    early_stop_table((160, 1000) if args.quick else (160, 1000), seeds=1 if args.quick else 3)
    if not args.quick:
        accuracy(args.seeds)
    return 0


def paper_constraints(seed, m=50):
    """The paper's four vx_dot constraints (vx = 0; all demand vx_dot = 0)."""
    from priors.registry import get_constraints
    return get_constraints("paper", "vx_dot").sample(NAMES, n_per_constraint=m, seed=seed)


def accuracy(seeds):
    """The paper's comparison in kind: medians over seeds on 160 training samples (eight) and
    251 test samples (square path), paper budget."""
    X, y = drone_data(160, seed=260)
    Xt, yt = drone_data(251, seed=7, path="square")
    cs_train, cs_test = paper_constraints(1), paper_constraints(2)
    priors = ["9.81*cos(yaw)*tan(pitch)/cos(roll)", "9.81*sin(yaw)*tan(roll)", "-0.28*vx"]
    A = lambda Z: np.column_stack([np.ones(len(Z))] + [  # noqa: E731
        9.81 * np.cos(Z[:, 3]) * np.tan(Z[:, 1]) / np.cos(Z[:, 2]),
        9.81 * np.sin(Z[:, 3]) * np.tan(Z[:, 2]), -0.28 * Z[:, 0]])
    beta, *_ = np.linalg.lstsq(A(X), y, rcond=None)
    prior_only = float(np.sqrt(np.mean((A(Xt) @ beta - yt) ** 2)))
    print(f"\n## Accuracy (median of {seeds} seeds; 160 train / 251 test samples; noise {NOISE})")
    print(f"prior-only least squares (3 tilt-drag terms): test rmse {prior_only:.4f}")
    print(f"{'setting':<28} {'rmse train':>10} {'rmse test':>9} {'e_c test':>9} {'qualified':>9} {'cpu s':>6}")
    for label, pri, cs in (("no prior", (), None), ("3 priors", priors, None),
                           ("no prior, constrained", (), cs_train),
                           ("3 priors, constrained", priors, cs_train)):
        rows = []
        for seed in range(1, seeds + 1):
            c0 = time.process_time()
            m = SNGPRegressor(seed=seed, early_stop_window=None).fit(X, y, feature_names=NAMES, priors=pri,
                                                                     constraints=cs)
            rows.append((m.rmse_train_, m.rmse(Xt, yt), m.constraint_rmse(cs_test), m.qualified_,
                         time.process_time() - c0))
        med = [statistics.median(r[i] for r in rows) for i in (0, 1, 2, 4)]
        q = sum(r[3] for r in rows)
        print(f"{label:<28} {med[0]:10.4f} {med[1]:9.4f} {med[2]:9.3g} {q:>5}/{seeds:<3} {med[3]:6.2f}")


if __name__ == "__main__":
    sys.exit(main())
