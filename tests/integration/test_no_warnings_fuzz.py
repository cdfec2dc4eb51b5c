"""The fuzz of issue 29 item 3 beyond ``inspect``: ``identify``, ``diagnose``, ``predict`` and
``dataset`` on damaged copies of a short simulated flight in every format droneid writes (tlog,
MCAP, Motive CSV, flat CSV), in-process with Python warnings turned into errors.

Each run must end with exit 0 or with exit 2 and ONE error line naming the problem; a Python
warning (raised as an exception under ``simplefilter("error")``, or printed) fails the test,
and so does a traceback or a control character from the file in an error line. Real logs get
the same treatment in tests/real_logs/test_no_warnings_fuzz_real.py.
"""
from __future__ import annotations

import contextlib
import io
import json
import random
import warnings

import pytest

from droneid.cli import main
from fuzz_check import mutate

#: the cheapest budgets (the data handling is the default one: effects and delays chosen)
IDENTIFY = ["--runs", "1", "--generations", "50", "--population", "60", "--jobs", "1"]
DIAGNOSE = ["--generations", "0"]
FORMATS = (".tlog", ".mcap", ".motive.csv", ".flat.csv")


def run_warnings_as_errors(argv) -> tuple[int, str]:
    """(exit code, stderr) of ``droneid ARGV`` in-process with every warning an error; a warning
    that escapes as an exception fails the test with the warning's text."""
    err = io.StringIO()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            try:
                rc = main([str(a) for a in argv])
            except Warning as w:                        # what the user would have seen
                pytest.fail(f"droneid {' '.join(map(str, argv))}: {type(w).__name__}: {w}")
            except SystemExit as exc:                   # argparse
                rc = exc.code if isinstance(exc.code, int) else 2
    return rc, err.getvalue()


def check(argv, what: str) -> int:
    rc, err = run_warnings_as_errors(argv)
    assert "Traceback" not in err, f"{what}: traceback\n{err[-2000:]}"
    assert "Warning" not in err, f"{what}: a warning reached the user\n{err[-2000:]}"
    assert rc in (0, 2), f"{what}: exit {rc}\n{err[-2000:]}"
    if rc == 2:
        lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("droneid: WARNING: ")]
        assert len(lines) == 1 and "error:" in lines[0], f"{what}: exit 2 needs ONE error line:\n{err[-2000:]}"
        assert all(c.isprintable() for c in lines[0]), f"{what}: control character in {lines[0]!r}"
    return rc


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> dict[str, bytes]:
    """One short simulated flight (motor speeds logged) in every written format, as bytes."""
    from droneid.simulation.simulator import simulate
    from parsers.csv_writer import write_flat_csv
    from parsers.mcap_writer import write_mcap
    from parsers.motive_writer import write_motive_csv
    from parsers.tlog_writer import write_tlog
    d = tmp_path_factory.mktemp("flight")
    flight = simulate(path="eight", duration_s=8, rate_hz=50, seed=4).flight
    out = {}
    for ext, write in zip(FORMATS, (write_tlog, write_mcap, write_motive_csv, write_flat_csv)):
        write(flight, d / f"f{ext}")
        out[ext] = (d / f"f{ext}").read_bytes()
    return out


@pytest.fixture(scope="module")
def result(logs, tmp_path_factory):
    """A result identified on the intact tlog (predict applies it to the damaged copies)."""
    d = tmp_path_factory.mktemp("result")
    (d / "f.tlog").write_bytes(logs[".tlog"])
    assert check(["identify", d / "f.tlog", "--prior", "tilt-drag", *IDENTIFY, "-q", "--report", d / "rep"],
                 "identify on the intact log") == 0
    return d / "rep" / "result.json"


@pytest.mark.slow
def test_intact_logs_pass_every_command(logs, result, tmp_path):
    """The control: every command accepts every intact format (so a mutant's refusal is about
    its damage)."""
    for ext, data in logs.items():
        p = tmp_path / f"intact{ext}"
        p.write_bytes(data)
        assert check(["dataset", p, "-o", tmp_path / "t.csv"], f"dataset {ext}") == 0
        assert check(["predict", result, p], f"predict {ext}") == 0
    assert json.loads(result.read_text(encoding="utf-8"))["targets"]


@pytest.mark.slow
@pytest.mark.parametrize("ext", FORMATS)
def test_damaged_logs_raise_no_warning_in_any_command(ext, logs, result, tmp_path):
    rng = random.Random(2929)
    outcomes = {0: 0, 2: 0}
    for k in range(6):
        kind, damaged = mutate(logs[ext], rng)
        p = tmp_path / f"m{k}{ext}"
        p.write_bytes(damaged)
        what = f"{ext} mutant {k} ({kind})"
        outcomes[check(["dataset", p, "-o", tmp_path / "t.csv"], f"dataset on {what}")] += 1
        outcomes[check(["predict", result, p, "--horizons", "1,10"], f"predict on {what}")] += 1
        if k < 3:                     # the search commands cost more: half of the mutants
            outcomes[check(["identify", p, *IDENTIFY, "-q"], f"identify on {what}")] += 1
            outcomes[check(["diagnose", p, *DIAGNOSE, "-q"], f"diagnose on {what}")] += 1
    assert sum(outcomes.values()) == 18
