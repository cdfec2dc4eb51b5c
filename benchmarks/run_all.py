"""Run every benchmark in this folder and print its figures: ``make bench``.

Each ``bench_*.py`` module exposes ``main(argv=None) -> int`` and prints its own table.
Pass a name filter to run a subset: ``python benchmarks/run_all.py read sngp``.
"""
from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    here = Path(__file__).resolve().parent
    failures = 0
    for path in sorted(here.glob("bench_*.py")):
        if argv and not any(a in path.stem for a in argv):
            continue
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        print(f"=== {path.stem}", flush=True)
        t0 = time.perf_counter()
        rc = module.main([])
        print(f"=== {path.stem}: exit {rc}, {time.perf_counter() - t0:.1f} s\n", flush=True)
        failures += rc != 0
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
