"""The fuzz of issue 29 item 3 beyond ``inspect``, on the shared real logs: ``predict`` (a result
identified on a shipped sample log) and ``dataset`` on damaged copies of every shared log, and
``diagnose`` (no open-ended search) on one damaged copy of each, in-process with Python warnings
turned into errors. The check (exit 0, or exit 2 with one printable error line; no warning, no
traceback) is tests/integration/test_no_warnings_fuzz.py's."""
from __future__ import annotations

import random
import sys

import pytest

from conftest import ROOT, SAMPLE_LOGS, real_log
from fuzz_check import mutate
from test_no_warnings_real import LOGS

sys.path.insert(0, str(ROOT / "tests" / "integration"))
from test_no_warnings_fuzz import DIAGNOSE, IDENTIFY, check  # noqa: E402

pytestmark = pytest.mark.real_logs

N_MUTANTS = 3


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    d = tmp_path_factory.mktemp("result")
    assert check(["identify", SAMPLE_LOGS / "paper_train_eight.tlog", "--prior", "tilt-drag", *IDENTIFY,
                  "-q", "--report", d], "identify on the sample log") == 0
    return d / "result.json"


@pytest.mark.slow
@pytest.mark.parametrize("rel", sorted(LOGS))
def test_damaged_real_logs_raise_no_warning_in_any_command(rel, result, tmp_path):
    src = real_log(rel)
    data = src.read_bytes()
    rng = random.Random(29)
    suffix = ".motive.csv" if "motive" in src.name else src.suffix
    for k in range(N_MUTANTS):
        kind, damaged = mutate(data, rng)
        p = tmp_path / f"m{k}{suffix}"
        p.write_bytes(damaged)
        what = f"mutant {k} ({kind}) of {rel}"
        opts = LOGS[rel]
        check(["dataset", p, *opts, "-o", tmp_path / "t.csv"], f"dataset on {what}")
        check(["predict", result, p, *opts], f"predict on {what}")
        if k == 0:
            check(["diagnose", p, *opts, *DIAGNOSE, "-q"], f"diagnose on {what}")
