"""No Python warning reaches the user from ANY command that reads logs (issue 29, item 3): on every
shared real log, ``inspect``, ``identify`` (the cheapest budget, default data handling: effects
and delays chosen as a user's run would), ``diagnose`` (small open-ended search), ``predict`` (with
the log's own result, with multi-step horizons, and with a result identified on a sample log) and
``export`` (every language) run in subprocesses with warnings turned into errors
(``python -W error`` and ``PYTHONWARNINGS=error``, which also reach worker processes).

Each command must exit 0, or exit 2 with ONE line on stderr (a refusal); never a traceback, never
a warning. ``tests/real_logs/test_no_warnings_real.py`` pins the list of shared logs and the
options each needs. Set ``DRONEID_WALK_DIR`` to keep every command's output (the closing walk
through the shared logs is written from it).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT, SAMPLE_LOGS, real_log
from test_no_warnings_real import LOGS

pytestmark = pytest.mark.real_logs

#: the cheapest identify budget (as tests/integration/test_docs_commands.py)
IDENTIFY = ["--runs", "1", "--generations", "200", "--population", "60", "--jobs", "1"]
DIAGNOSE = ["--generations", "200"]
#: a warning line as Python prints it, or an exception raised from one under -W error
WARNING = re.compile(r"\b\w*Warning\b")


def run(*argv, name: str | None = None) -> subprocess.CompletedProcess:
    """``python -W error -m droneid ARGV`` (PYTHONWARNINGS=error for its workers too)."""
    env = {**os.environ, "PYTHONWARNINGS": "error"}
    r = subprocess.run([sys.executable, "-W", "error", "-m", "droneid", *map(str, argv)],
                       capture_output=True, text=True, cwd=ROOT, timeout=900, env=env)
    keep = os.environ.get("DRONEID_WALK_DIR")
    if keep and name:
        Path(keep).mkdir(parents=True, exist_ok=True)
        (Path(keep) / f"{name}.txt").write_text(
            f"$ droneid {' '.join(map(str, argv))}\n# exit {r.returncode}\n{r.stdout}\n# stderr\n{r.stderr}",
            encoding="utf-8")
    return r


def check(r: subprocess.CompletedProcess, what: str) -> int:
    """Exit 0, or exit 2 with one stderr line; no traceback, no warning."""
    err = r.stderr
    assert "Traceback" not in err, f"{what}: traceback\n{err[-3000:]}"
    assert not WARNING.search(err), f"{what}: a Python warning reached the user\n{err[-3000:]}"
    assert r.returncode in (0, 2), f"{what}: exit {r.returncode}\n{err[-3000:]}"
    if r.returncode == 2:
        # droneid's own logged lines ("droneid: WARNING: <file>: 1 reader warning(s) ...") may
        # precede the refusal; the refusal itself is one line
        lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("droneid: WARNING: ")]
        assert len(lines) == 1 and "error:" in lines[0], f"{what}: exit 2 needs ONE error line:\n{err[-3000:]}"
    return r.returncode


def _slug(rel: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", Path(rel).stem)


@pytest.fixture(scope="module")
def sample_result(tmp_path_factory) -> Path:
    """A result identified on a shipped sample log (tilt-drag): predict applies it to every real
    log, including the ones identify refuses."""
    out = tmp_path_factory.mktemp("sample")
    r = run("identify", SAMPLE_LOGS / "paper_train_eight.tlog", "--prior", "tilt-drag", *IDENTIFY,
            "-q", "--report", out)
    assert check(r, "identify on the sample log") == 0
    return out / "result.json"


@pytest.mark.slow
@pytest.mark.parametrize("rel", sorted(LOGS))
def test_every_command_with_warnings_as_errors(rel, sample_result, tmp_path):
    path, opts, slug = real_log(rel), LOGS[rel], _slug(rel)
    check(run("inspect", path, *opts, name=f"{slug}.inspect"), f"inspect {rel}")
    rep = tmp_path / "identify"
    rc = check(run("identify", path, *opts, *IDENTIFY, "-q", "--report", rep, name=f"{slug}.identify"),
               f"identify {rel}")
    check(run("diagnose", path, *opts, *DIAGNOSE, "-q", name=f"{slug}.diagnose"), f"diagnose {rel}")
    check(run("predict", sample_result, path, *opts, name=f"{slug}.predict_sample"),
          f"predict (sample result) on {rel}")
    if rc != 0:
        return
    result = rep / "result.json"
    assert json.loads(result.read_text(encoding="utf-8"))["targets"]
    # the result's own reader options apply by default (the Motive body among them)
    check(run("predict", result, path, "--horizons", "1,10", name=f"{slug}.predict"), f"predict on {rel}")
    for lang in ("python", "c", "matlab", "latex"):
        out = tmp_path / f"model.{lang}"
        assert check(run("export", result, "--to", lang, "-o", out), f"export --to {lang} ({rel})") == 0
        assert out.read_text(encoding="utf-8").strip()
