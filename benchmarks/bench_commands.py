"""Does identify recover a command-driven vehicle's thrust curve and battery compensation (issue 36)?

    .venv/bin/python benchmarks/bench_commands.py [--seeds 10] [--jobs 2]

Simulated vehicles (:func:`droneid.simulation.simulator.simulate`, known truth) that log motor commands but
no rotor speeds (rpm1..4 removed): per seed the thrust curve's shape ``thrust_expo`` e drawn from
[0.3, 0.7], a first-order motor lag from [20, 80] ms, and on two seeds of three a battery sagging
from 4.2 to 3.3 V per cell (3S: 12.6 -> 9.9 V over each flight, ArduPilot's voltage scaling:
thrust of a command ∝ f_e(u·V/12.6)). Three training flights (random, eight, lissajous; 30 s,
climbing and descending 0.5 m) and one test flight (square). identify's pipeline on the training
flights (prior auto -> rotor-thrust on the commands, v̇z, no effects folded, a token SNGP budget:
only the physical model is scored).

Per vehicle: the identified e with its 95 % interval (covers the planted e?), the motor lag fitted
with its 95 % interval (kept by the block test and covering the planted lag?), whether the battery
compensation was kept (it should be exactly when the battery sags), and the v̇z test RMSE of the
final model against the TRUE model's: the simulator's own vertical acceleration (motor lag and
all: what is left is the target's differentiation noise). "no lag" is the planted curve, battery
scaling, thrust per command and drag on the logged commands without the lag. Targets: e covered,
the lag kept and covered, battery decided right, and the test RMSE within 10 % of the true model's,
each on every vehicle.
Exit 0 when all are met, 1 otherwise.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

V_FULL, V_EMPTY = 12.6, 9.9      # 3S: 4.2 -> 3.3 V per cell
TRAIN_PATHS = ("random", "eight", "lissajous")


def case_spec(seed: int) -> dict:
    rng = np.random.default_rng([seed, 36])
    expo = round(float(rng.uniform(0.3, 0.7)), 3)
    lag = round(float(rng.uniform(0.02, 0.08)), 3)
    sag = seed % 3 != 2
    flights = []
    for j, path in enumerate((*TRAIN_PATHS, "square")):
        eff = {"thrust_variation": {"amp_m": 0.5, "period_s": 3.0 + j % 3}}
        if sag:
            eff["battery_sag"] = {"v_start": V_FULL, "v_end": V_EMPTY, "exponent": 2.0}
        flights.append({"path": path, "duration_s": 30.0, "rate_hz": 100.0, "seed": 1000 * seed + j,
                        "effects": eff, "thrust_expo": expo, "motor_tau_s": lag})
    return {"seed": seed, "expo": expo, "lag_s": lag, "sag": sag, "flights": flights}


def _true_rmse(sim, t_rows, ts: float) -> tuple[float, float]:
    """v̇z RMSE on the test flight's rows at ``t_rows`` (s) of (the true command model without the
    lag, the true dynamics: the simulator's own acceleration, motor lag included)."""
    from droneid.dataset.builder import DatasetBuilder
    from priors.thrust import thrust_curve

    tr = sim.truth
    inputs = ("vz", "roll", "pitch", "motor1", "motor2", "motor3", "motor4", "battery_voltage")
    ds = DatasetBuilder(ts=ts, method="central").build([sim.flight], target="vz_dot", inputs=inputs)
    keep = np.isin(np.round(ds.t, 6), np.round(np.asarray(t_rows, float), 6))
    c = {k: v[keep] for k, v in ds.columns().items()}
    s = c["battery_voltage"] / tr["rotors"]["v_ref"] if tr["effects"].get("battery_sag") else 1.0
    u = np.column_stack([c[f"motor{i}"] for i in range(1, 5)])
    thrust = tr["rotors"]["k_cmd"] * np.sum(thrust_curve(u * np.atleast_1d(s)[:, None], tr["rotors"]["thrust_expo"]), axis=1)
    pred = thrust * np.cos(c["roll"]) * np.cos(c["pitch"]) - tr["params"]["g"] - tr["params"]["k_drag"] * c["vz"]
    exact = np.interp(ds.t[keep], np.asarray(tr["t"]), np.asarray(tr["az"]))
    return (float(np.sqrt(np.mean((ds.y[keep] - pred) ** 2))),
            float(np.sqrt(np.mean((ds.y[keep] - exact) ** 2))))


def run_case(spec: dict) -> dict:
    warnings.simplefilter("ignore")
    from droneid import Identifier
    from droneid.simulation.simulator import simulate

    t0 = time.perf_counter()
    sims = [simulate(**f) for f in spec["flights"]]
    flights = [s.flight.without("rpm1", "rpm2", "rpm3", "rpm4") for s in sims]
    res = Identifier(effects="none", targets="vz_dot", rotation="none", runs=1, generations=50,
                     population_size=40, jobs=1).fit(flights[:3], test=flights[3:])
    curve = res.plan.thrust_curve
    tr = res.targets["vz_dot"]
    final = tr.ladder[-1]
    no_lag, true = _true_rmse(sims[3], tr.test_series["t"], res.config.ts)
    offset = res.plan.offset["offset_s"] if res.plan.offset else 0.0
    return {**{k: spec[k] for k in ("seed", "expo", "lag_s", "sag")}, "e": curve["expo"],
            "low": curve["interval"][0], "high": curve["interval"][1], "voltage": curve["voltage"],
            "rmse_test": final.rmse_test, "rmse_true": true, "rmse_no_lag": no_lag, "offset_s": offset,
            "hover": curve["hover"], "lag_fit": curve["lag_s"] or curve["lag_tried_s"], "lag_kept": curve["lag_s"] > 0,
            "lag_low": curve["lag_interval"][0], "lag_high": curve["lag_interval"][1], "secs": time.perf_counter() - t0}


def run_cases(name: str, description: str, run, argv=None) -> list:
    """The results of ``run`` on every vehicle's :func:`case_spec`: ``--seeds`` vehicles
    on ``--jobs`` worker processes, and the benchmark's ``name`` line with the wall time (the
    command-line frame this benchmark and bench_commands_open_loop.py share)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--seeds", type=int, default=10, help="vehicles (default 10)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    args = ap.parse_args(argv)
    specs = [case_spec(s) for s in range(args.seeds)]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as ex:
        results = list(ex.map(run, specs))
    print(f"{name}: {args.seeds} command-driven vehicles, 3 training + 1 test flight each, wall "
          f"{time.perf_counter() - t0:.0f} s (CPU load {os.getloadavg()[0]:.1f})")
    return results


def main(argv=None) -> int:
    results = run_cases("bench_commands", __doc__.splitlines()[0], run_case, argv)
    print(f"{'seed':>4s} {'expo':>5s} {'lag':>6s} {'sag':>3s} {'e':>6s} {'interval':>15s} {'covers':>6s} "
          f"{'offset':>7s} {'battery':>7s} {'right':>5s} {'vz test':>7s} {'true':>7s} {'ratio':>6s} {'no lag':>7s} "
          f"{'lag fit':>7s} {'lag interval':>13s} {'covers':>6s}")
    cov = batt = close = lag_cov = 0
    for r in results:
        c = r["low"] <= r["expo"] <= r["high"]
        b = r["voltage"] is r["sag"]
        ratio = r["rmse_test"] / r["rmse_true"] if r["rmse_true"] > 0 else math.inf
        lc = r["lag_kept"] and r["lag_low"] <= r["lag_s"] <= r["lag_high"]
        cov, batt, close, lag_cov = cov + c, batt + b, close + (ratio <= 1.10), lag_cov + lc
        print(f"{r['seed']:4d} {r['expo']:5.3f} {1000 * r['lag_s']:4.0f}ms {'yes' if r['sag'] else 'no':>3s} "
              f"{r['e']:6.3f} [{r['low']:5.3f}, {r['high']:5.3f}] {'yes' if c else 'NO':>6s} "
              f"{1000 * r['offset_s']:+5.0f}ms {'kept' if r['voltage'] else 'no':>7s} {'yes' if b else 'NO':>5s} "
              f"{r['rmse_test']:7.4f} {r['rmse_true']:7.4f} {ratio:6.3f} {r['rmse_no_lag']:7.4f} "
              f"{1000 * r['lag_fit']:5.1f}ms [{1000 * r['lag_low']:4.1f}, {1000 * r['lag_high']:4.1f}] "
              f"{'yes' if lc else 'NO':>6s}")
    n = len(results)
    print(f"e covered by its interval: {cov}/{n}; battery compensation decided right: {batt}/{n}; "
          f"v̇z test RMSE within 10 % of the true model's: {close}/{n}; motor lag kept and covered by its "
          f"interval: {lag_cov}/{n}")
    met = cov == batt == close == lag_cov == n
    print("targets " + ("met" if met else "NOT met"))
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
