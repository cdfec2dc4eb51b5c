"""Golden summaries pin what each reader makes of the real logs (signals, counts, spans, sources,
segments, skipped damage). After an intended change: tests/golden/regenerate.py, review the diff."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from parsers import read_flight

from conftest import real_log

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "golden"))
from regenerate import LOGS, golden_name, pinned  # noqa: E402

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
pytestmark = pytest.mark.real_logs


@pytest.mark.parametrize("rel", sorted(LOGS))
def test_reader_matches_golden(rel):
    path = real_log(rel)
    want = json.loads((GOLDEN / golden_name(rel)).read_text())
    got = json.loads(json.dumps(pinned(read_flight(path, **LOGS[rel]))))
    assert got["signals"].keys() == want["signals"].keys()
    for name, row in want["signals"].items():
        assert got["signals"][name] == row, name
    assert got == want
