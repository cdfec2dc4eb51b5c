"""Speed of the SNGP engine at the paper's budget, against the authors' Java SNGP.

    .venv/bin/python benchmarks/bench_sngp.py [--repeats R] [--quick]

Paper budget (Table I): population 500, 60 000 generations, nf 10, depth 7, function set
{+, -, x, square, cube, sin, cos}. Data: drone-like samples along an eight (tilt-drag model with
a planted quadratic drag -0.3|vx|vx the model lacks, noise 0.05 m/s^2), test set on a different
path. Prints wall and CPU time per run, generations/s, node evaluations/s, scaling with samples
and generations (ratios), the speed-up over the reference (22 s on 160 samples, 155 s on 1 000
samples on this 2-core machine), and test errors (noise floor 0.05) to show accuracy is kept.
One core: the search is single-threaded. Other processes on a shared machine inflate wall time;
CPU time (process_time) is the fairer figure then.
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from droneid.sngp import SNGPRegressor  # noqa: E402

NAMES = ["vx", "pitch", "roll", "yaw"]
REFERENCE_S = {160: 22.0, 1000: 155.0}
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
    est = SNGPRegressor(generations=generations, seed=seed)   # defaults: paper budget
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1, help="runs per setting (median reported)")
    ap.add_argument("--quick", action="store_true", help="only the two headline runs")
    ap.add_argument("--seeds", type=int, default=5, help="runs per setting in the accuracy table")
    args = ap.parse_args(argv)
    X_test, y_test = drone_data(251, seed=7, path="square")

    print(f"# SNGP benchmark: {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} (other processes share "
          "the machine: wall time is inflated, CPU time is the fairer figure)")
    t = time.perf_counter()
    SNGPRegressor(generations=200, seed=0, simplify_s=0).fit(*drone_data(50, 0), feature_names=NAMES)
    print(f"# warm-up (numba compile or cache load): {time.perf_counter() - t:.1f} s")

    print("\n## Paper budget (population 500, 60 000 generations, nf 10, depth 7, Table I set)")
    head = f"{'samples':>7} {'wall s':>7} {'cpu s':>7} {'search':>7} {'ref s':>6} {'speed-up':>9} {'gen/s':>8} " \
           f"{'node eval/s':>12} {'evals/gen':>9} {'rmse train':>10} {'rmse test':>9}"
    print(head)
    rows = {}
    sizes = (160, 1000) if args.quick else (160, 500, 1000)
    for n in sizes:
        r = median_run(n, 60000, args.repeats, X_test, y_test)
        rows[n] = r
        ref = REFERENCE_S.get(n)
        sp = f"{ref / r['cpu']:8.1f}x" if ref else f"{'':>9}"
        print(f"{n:>7} {r['wall']:7.2f} {r['cpu']:7.2f} {r['search_cpu']:7.2f} {ref if ref else '':>6} {sp} {r['gps']:8.0f} "
              f"{r['eps']:12.3g} {r['evals_per_gen']:9.1f} {r['train']:10.4f} {r['test']:9.4f}")
    print("(cpu s: the whole fit incl. pruning and sympy; search: the SNGP search alone (ratios use\n"
          " it); rates per CPU second of search."
          " Targets: <= 2.2 s on 160 samples, <= 15 s on 1000.)")

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
    if not args.quick:
        accuracy(args.seeds)
    return 0


def paper_constraints(seed, m=50):
    """The paper's four vx_dot constraints (vx = 0; all demand vx_dot = 0)."""
    from priors.constraints import get_constraints
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
            m = SNGPRegressor(seed=seed).fit(X, y, feature_names=NAMES, priors=pri, constraints=cs)
            rows.append((m.rmse_train_, m.rmse(Xt, yt), m.constraint_rmse(cs_test), m.qualified_,
                         time.process_time() - c0))
        med = [statistics.median(r[i] for r in rows) for i in (0, 1, 2, 4)]
        q = sum(r[3] for r in rows)
        print(f"{label:<28} {med[0]:10.4f} {med[1]:9.4f} {med[2]:9.3g} {q:>5}/{seeds:<3} {med[3]:6.2f}")


if __name__ == "__main__":
    sys.exit(main())
