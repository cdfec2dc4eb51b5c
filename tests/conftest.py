"""Shared test fixtures. Real logs are read from ../shared/real_logs and never copied here.

Tests are sorted by kind: ``unit/`` (one module, small data), ``integration/`` (pipelines and the
CLI end to end), ``real_logs/`` (public logs recorded on real vehicles). Every test under
``real_logs/`` carries the ``real_logs`` marker, and so does any other test that reads a real log
(the ``real_logs`` fixture or :func:`real_log`): ``-m "not real_logs"`` runs without them.
"""
from __future__ import annotations

import inspect
import os
from pathlib import Path

import pytest

import droneid  # noqa: F401  (first: it keeps BLAS to one thread before numpy loads, as the CLI does)

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


def pytest_collection_modifyitems(config, items):
    """The ``real_logs`` marker by folder, and on tests elsewhere that read a real log."""
    folder = Path(__file__).resolve().parent / "real_logs"
    for item in items:
        path = Path(str(item.fspath)).resolve()
        reads = "real_logs" in getattr(item, "fixturenames", ())
        if not reads and getattr(item, "function", None) is not None:
            try:
                reads = "real_log(" in inspect.getsource(item.function)
            except (OSError, TypeError):
                reads = False
        if folder in path.parents or reads:
            item.add_marker(pytest.mark.real_logs)
