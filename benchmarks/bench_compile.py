"""First-run compile time of the SNGP kernels, as a fresh clone or a fresh venv meets it.

    .venv/bin/python benchmarks/bench_compile.py

A fresh clone or venv differs from this one in one way that matters here: numba's cache of the
compiled kernels is empty. The benchmark points ``NUMBA_CACHE_DIR`` at an empty temporary folder
and, in a new process, imports droneid and calls :func:`droneid.sngp.warmup` (one tiny fit of every
variant, so every kernel is compiled); then a second process does the same with the cache
filled (what every later command pays). Wall and CPU time of each process are printed. ``make
install`` runs the same warm-up once, so the first command after it only loads the cache.
Target: <= 15 s of compilation.
"""
from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 15.0
_CODE = ("import time; t = time.perf_counter(); import droneid.sngp as s; ready = s.kernels_ready(); "
         "w = s.warmup(); print(ready, w, time.perf_counter() - t)")


def one_process(cache_dir: str) -> dict:
    """Run import + warm-up in a new process with ``cache_dir`` as numba's cache."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir, PYTHONPATH=str(ROOT))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", _CODE], env=env, cwd=ROOT, capture_output=True,
                         text=True, check=True).stdout.split()
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"ready_before": out[0] == "True", "warmup_s": float(out[1]), "import_and_warmup_s": float(out[2]),
            "process_wall_s": wall,
            "process_cpu_s": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)}


def run() -> dict:
    with tempfile.TemporaryDirectory(prefix="droneid-numba-cache-") as cache:
        return {"fresh": one_process(cache), "cached": one_process(cache)}


def main(argv=None) -> int:
    r = run()
    print(f"# {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    print(f"{'numba cache':<12} {'kernels ready':>13} {'warm-up s':>9} {'process wall s':>14} {'process CPU s':>13}")
    for label, f in (("empty", r["fresh"]), ("filled", r["cached"])):
        print(f"{label:<12} {str(f['ready_before']):>13} {f['warmup_s']:9.1f} {f['process_wall_s']:14.1f} "
              f"{f['process_cpu_s']:13.1f}")
    compile_s = r["fresh"]["warmup_s"] - r["cached"]["warmup_s"]
    print(f"compilation: {compile_s:.1f} s wall (warm-up with an empty cache minus with a filled one); "
          f"target <= {TARGET_S:.0f} s: {'met' if compile_s <= TARGET_S else 'NOT met'}"
          + (" (machine loaded: wall time inflated)" if os.getloadavg()[0] > 1.5 else ""))
    print("make install runs this warm-up once; the first command afterwards loads the cache "
          f"({r['cached']['warmup_s']:.1f} s).")
    return 0


if __name__ == "__main__":
    sys.exit(main())
