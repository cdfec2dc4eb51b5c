"""Benchmark: droneid's DataFlash reader vs a bare pymavlink loop over the same messages.

    .venv/bin/python benchmarks/bench_read.py [--repeat 3] [--json]

Reads ../shared/real_logs/ardupilot/copter33_quad_log171.bin (skipped with a message when
absent). The bare loop is what a user would write by hand: DFReader, ``recv_match`` over the same
message types, the same fields appended to Python lists, nothing converted. droneid's time includes
everything (conversion to ENU/FLU, cleaning, segments, events). Target: ratio <= 1.3.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOG = ROOT.parent / "shared" / "real_logs" / "ardupilot" / "copter33_quad_log171.bin"
TARGET_RATIO = 1.3


def bare_pymavlink(path) -> int:
    """The hand-written baseline: same message types and fields, kept as lists."""
    from operator import attrgetter

    from pymavlink import DFReader

    from parsers.dataflash_log import _WANT, MESSAGE_TYPES
    log = DFReader.DFReader_binary(str(path), zero_time_base=True)
    getters, out = {}, {}
    n = 0
    while True:
        m = log.recv_match(type=list(MESSAGE_TYPES))
        if m is None:
            break
        k = m.get_type()
        g = getters.get(k)
        if g is None:
            cols = m.get_fieldnames()
            fields = [f for f in ("TimeUS", "TimeMS", "T") if f in cols][:1] + [f for f in _WANT[k] if f in cols]
            g = getters[k] = attrgetter(*fields) if len(fields) > 1 else (lambda m, f=fields: tuple(getattr(m, x) for x in f))
            out[k] = []
        out[k].append(g(m))
        n += 1
    return n


def droneid_read(path) -> int:
    from parsers import read_flight
    f = read_flight(path)
    return sum(len(s) for s in f.signals.values())


def run(repeat: int = 3, path: Path = LOG) -> dict | None:
    """Best-of-``repeat`` wall times of both readers (alternating), or None when the log is absent."""
    if not Path(path).is_file():
        return None
    t_bare, t_ours = [], []
    n_bare = n_ours = 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        n_bare = bare_pymavlink(path)
        t_bare.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        n_ours = droneid_read(path)
        t_ours.append(time.perf_counter() - t0)
    bare, ours = min(t_bare), min(t_ours)
    return {"benchmark": "read_dataflash", "file": str(path), "messages": n_bare, "samples": n_ours,
            "bare_pymavlink_s": round(bare, 3), "droneid_s": round(ours, 3),
            "ratio": round(ours / bare, 3), "target_ratio": TARGET_RATIO,
            "ok": ours / bare <= TARGET_RATIO}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    res = run(args.repeat)
    if res is None:
        print(f"bench_read: skipped: {LOG} is absent (../shared/real_logs is not part of the repo)")
        return 0
    if args.json:
        print(json.dumps(res))
    else:
        print(f"{LOG.name}: {res['messages']} messages")
        print(f"  bare pymavlink loop : {res['bare_pymavlink_s']:.3f} s")
        print(f"  droneid read_flight : {res['droneid_s']:.3f} s ({res['samples']} samples, converted)")
        print(f"  ratio               : {res['ratio']:.2f}x (target <= {TARGET_RATIO}x) "
              f"{'OK' if res['ok'] else 'SLOWER THAN TARGET'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
