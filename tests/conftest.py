"""Shared test fixtures. Real logs are read from ../shared/real_logs and never copied here."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REAL_LOGS = Path(os.environ.get("DRONEID_REAL_LOGS") or ROOT.parent / "shared" / "real_logs")
SAMPLE_LOGS = ROOT / "sample_logs"


@pytest.fixture(scope="session")
def real_logs() -> Path:
    """The folder of public real-vehicle logs; skips the test where it is absent."""
    if not REAL_LOGS.is_dir():
        pytest.skip(f"real logs folder {REAL_LOGS} is absent (it lives beside the repo, not in it)")
    return REAL_LOGS


def real_log(relpath: str) -> Path:
    """One real log by its path below real_logs/, or skip with the reason."""
    p = REAL_LOGS / relpath
    if not p.is_file():
        pytest.skip(f"real log {p} is absent (../shared/real_logs is not part of this repo)")
    return p
