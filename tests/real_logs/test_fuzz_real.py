"""Damaged real logs never traceback, hang or flood (issue 14; moved from
tests/integration/test_fuzz_parsers.py): every real log under 3 MB, mutated four times with a
fixed seed, through ``droneid inspect``."""
from __future__ import annotations

import random

import pytest

from fuzz_check import check_inspect, mutate

pytestmark = pytest.mark.real_logs


@pytest.mark.slow
def test_fuzz_real_logs(tmp_path, real_logs):
    rng = random.Random(14)
    logs = sorted(p for p in real_logs.rglob("*")
                  if p.suffix in (".bin", ".px4log", ".tlog", ".ulg", ".mcap", ".csv")
                  and p.stat().st_size < 3_000_000)
    for src in logs:
        data = src.read_bytes()
        for k in range(4):
            kind, bad = mutate(data, rng)
            suffix = ".motive.csv" if "motive" in src.name else src.suffix
            p = tmp_path / f"r{k}{suffix}"
            p.write_bytes(bad)
            check_inspect(p, f"{src.name} #{k} ({kind})")
