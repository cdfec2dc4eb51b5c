"""A power curve (issue 37.3): the share of planted effects the diagnosis finds as flights are added.

    .venv/bin/python benchmarks/bench_power.py [--cases 12] [--counts 2,4,8] [--duration 12] [--jobs 2] [--seed 0] [--quick]

Each case is one simulated vehicle with planted effects (``bench_diagnose.flight_spec``: the
same catalogue, vehicles, paths and noise; every 4th case a control with none), flown ``n`` times
(the same path, other seeds: other noise, gusts and start) and diagnosed on those ``n`` flights
together (:func:`droneid.diagnosis.diagnose.diagnose`, its defaults, training flights only), for every
``n`` of ``--counts``. Flights are short (``--duration``, default 12 s) so that two flights
leave some effects unproven: the curve is what more flights buy. The flights of a smaller count
are the first flights of the larger (nested).

Prints per flight count the share of planted effects found (recall), the effects added that were
not planted (false positives; controls' separately) and the wall time; the rule's promise
(issue 37): the share found must not fall as flights are added, and false positives must not
rise. Exit 1 when the share found falls from one count to the next. ``--quick``: 6 cases, counts
2 and 4, 10 s flights.

The ω̇ rungs (``--no-rotation`` leaves them out): the planted rigid-body rotation of
tests/unit/test_rotation_planted.py (a torque model with rotor drag and decay, each flight with
its own balance point; 15 s flights from smooth random motor speeds, the flights of a smaller
count the start of the larger), chosen by identify's rotational stage
(:func:`droneid.rotation.choice.select_rotation`, its defaults but the planted model's terms as
the one torque candidate): per flight count the share of the three axes that reach the planted
torque rung.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
for p in (HERE, HERE.parent):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from bench_diagnose import flight_spec, run_flight, score  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=12, help="simulated vehicles (default 12)")
    ap.add_argument("--counts", default="2,4,8", help="flights per case, comma-separated (default 2,4,8)")
    ap.add_argument("--duration", type=float, default=12.0, help="flight length s (default 12)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the case set (default 0)")
    ap.add_argument("--quick", action="store_true", help="6 cases, counts 2 and 4, 10 s flights")
    ap.add_argument("--no-rotation", action="store_true", help="leave out the ω̇ rungs")
    args = ap.parse_args(argv)
    cases = 6 if args.quick else args.cases
    counts = [2, 4] if args.quick else [int(c) for c in args.counts.split(",")]
    duration = 10.0 if args.quick else args.duration
    if cases < 1 or any(c < 1 for c in counts):
        ap.error("--cases and every count must be at least 1")
    specs = [flight_spec(i, args.seed, duration) for i in range(cases)]
    jobs = [{**s, "copies": n} for n in counts for s in specs]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as ex:
        results = list(ex.map(run_flight, jobs))
    wall = time.perf_counter() - t0
    planted = sum(len(s["planted"]) for s in specs)
    print(f"bench_power: {cases} cases ({sum(1 for s in specs if not s['planted'])} controls, {planted} planted "
          f"effects), {duration:g} s flights, diagnose defaults, seed {args.seed}, {args.jobs} workers, wall "
          f"{wall:.0f} s (load {os.getloadavg()[0]:.1f})")
    print(f"{'flights':>7s} {'found':>7s} {'share':>6s} {'false +':>7s} {'on controls':>11s}  per effect found/planted")
    shares, ok = [], True
    for n in counts:
        got = [r for r in results if r["copies"] == n]
        s = score(got)
        shares.append(s["recall"])
        per = ", ".join(f"{e} {v['tp']}/{v['tp'] + v['fn']}" for e, v in s["per_effect"].items() if v["tp"] + v["fn"])
        print(f"{n:7d} {s['tp']:3d}/{planted:<3d} {s['recall']:6.2f} {s['fp']:7d} {len(s['control_fp']):11d}  {per}")
    for a, b, (na, nb) in zip(shares, shares[1:], zip(counts, counts[1:])):
        if b < a:
            ok = False
            print(f"the share found FALLS from {na} to {nb} flights ({a:.2f} -> {b:.2f})")
    if not args.no_rotation:
        ok = _rotation_curve(counts) and ok
    print(f"the share found never falls as flights are added: {'yes' if ok else 'NO'}")
    return 0 if ok else 1


def _rotation_curve(counts: list[int]) -> bool:
    """The ω̇ rungs' power curve (module docstring); True when the share never falls."""
    sys.path.insert(0, str(HERE.parent / "tests" / "unit"))
    from test_rotation_planted import DRAG_TERMS, _balanced_flight   # the planted rotation of the tests
    from droneid.rotation.choice import select_rotation
    rng = np.random.default_rng(7)
    t0 = time.perf_counter()
    logs = [_balanced_flight(100 + i, rng.uniform(-500.0, 500.0, 4), name=f"planted{i}") for i in range(max(counts))]
    shares = []
    print(f"ω̇ rungs: the planted torque model on 3 axes, {len(logs)} simulated flights of 15 s, select_rotation")
    for n in counts:
        ch = select_rotation(logs[:n], candidates=({"terms": DRAG_TERMS, "balance_weight_s": 1.0},),
                             translation_delay_steps=0, stride=10)
        took = sum(r == "torque" for r in ch.axis_choice)
        shares.append(took / 3)
        cells = max(st["cells"] for ax in ch.ladder for st in ax["steps"])
        print(f"{n:7d} {took:3d}/3   {took / 3:6.2f}  rungs {'/'.join(ch.axis_choice)} ({cells} cells per step)")
    print(f"(ω̇: {time.perf_counter() - t0:.0f} s)")
    return all(b >= a for a, b in zip(shares, shares[1:]))


if __name__ == "__main__":
    sys.exit(main())
