"""benchmarks/bench_read.py runs and reads what the bare pymavlink loop reads.

Its speed ratio is a figure the benchmark prints (make bench), not a pass/fail test here."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from conftest import real_log


@pytest.mark.slow
def test_bench_read_runs_and_counts():
    real_log("ardupilot/copter33_quad_log171.bin")
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_read.py"
    spec = importlib.util.spec_from_file_location("bench_read", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    res = mod.run(repeat=1)
    assert res["messages"] > 30000 and res["samples"] > 100000
