"""Numbers shown in README.md and docs/*.md from commands on the shared real logs are what those
commands print now (issue 29, item 7): the README's worked example (identify --quick on the
Crazyflie squares, tested on the melon runs) and docs/use-the-model.md's predict on its result.
The rules (which blocks are output, how lines are compared) are in
tests/integration/test_docs_numbers.py; every command runs with its documented budget, and the
README's identify runs once for both documents."""
from __future__ import annotations

import sys

import pytest

from conftest import REAL_LOGS, ROOT

sys.path.insert(0, str(ROOT / "tests" / "integration"))
from test_docs_numbers import ALL_SHOWN, check_shown  # noqa: E402

pytestmark = [pytest.mark.real_logs, pytest.mark.slow]


@pytest.fixture(scope="session")
def docs_folder(tmp_path_factory):
    return tmp_path_factory.mktemp("docs_run_real")


@pytest.mark.parametrize("shown", [s for s in ALL_SHOWN if s.uses_real_logs], ids=str)
def test_shown_output_on_real_logs_is_current(shown, docs_folder):
    if not REAL_LOGS.is_dir():
        pytest.skip(f"real logs folder {REAL_LOGS} is absent (it lives beside the repo, not in it)")
    check_shown(shown, docs_folder)
