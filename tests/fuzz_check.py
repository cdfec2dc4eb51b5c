"""``droneid inspect`` on damaged logs, for the fuzz tests of issue 14
(tests/integration/test_fuzz_parsers.py, tests/real_logs/test_fuzz_real.py): the mutations, the
in-process run with a time limit, and the check of its outcome."""
from __future__ import annotations

import contextlib
import io
import logging
import random
import threading
import time

from droneid.cli import main

PER_FILE_S = 20.0


def mutate(data: bytes, rng: random.Random) -> tuple[str, bytes]:
    """One random damage of ``data``: (kind, damaged bytes); kind is flip, truncate, garbage,
    zero or header."""
    b = bytearray(data)
    kind = rng.choice(["flip", "truncate", "garbage", "zero", "header"])
    if kind == "flip":
        for _ in range(rng.randint(1, 40)):
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
    elif kind == "truncate":
        b = b[:rng.randrange(1, len(b))]
    elif kind == "garbage":
        i = rng.randrange(len(b))
        b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 400)))
    elif kind == "zero":
        i = rng.randrange(len(b))
        n = rng.randint(1, 1500)
        b[i:i + n] = bytes(len(b[i:i + n]))
    else:
        for _ in range(rng.randint(1, 4)):
            b[rng.randrange(min(len(b), 400))] = rng.randrange(256)
    return kind, bytes(b)


def inspect_in_process(path, *args) -> tuple[int | None, list[str], float]:
    """``droneid inspect PATH`` in a daemon thread: (exit code or None on timeout, stderr lines
    incl. logged warnings, seconds)."""
    err = io.StringIO()
    handler = logging.StreamHandler(err)
    handler.setLevel(logging.WARNING)
    result = {}

    def run():
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            try:
                result["rc"] = main(["inspect", str(path), *args])
            except SystemExit as exc:  # argparse
                result["rc"] = exc.code
            except BaseException as exc:  # noqa: BLE001 - a traceback is the failure we look for
                import traceback
                err.write("Traceback (in-process)\n" + "".join(traceback.format_exception(exc)))
                result["rc"] = 1

    root = logging.getLogger()
    root.addHandler(handler)
    t0 = time.perf_counter()
    try:
        th = threading.Thread(target=run, daemon=True)
        th.start()
        th.join(PER_FILE_S)
    finally:
        root.removeHandler(handler)
    return result.get("rc"), [ln for ln in err.getvalue().splitlines() if ln.strip()], \
        time.perf_counter() - t0


def check_inspect(path, what):
    """``droneid inspect PATH`` finishes in time with exit 0 (at most one warning line) or exit 2
    with ONE stderr line naming the file, and no traceback; returns the exit code."""
    rc, lines, dt = inspect_in_process(path)
    assert rc is not None, f"{what}: inspect did not finish within {PER_FILE_S} s (hang)"
    text = "\n".join(lines)
    assert "Traceback" not in text, f"{what}: traceback\n{text}"
    assert rc in (0, 2), f"{what}: exit {rc}\n{text}"
    if rc == 2:
        assert len(lines) == 1, f"{what}: exit 2 needs ONE stderr line, got {len(lines)}:\n{text[:2000]}"
        assert str(path) in lines[0], f"{what}: the error line must name the file: {lines[0]}"
    else:
        assert len(lines) <= 1, f"{what}: exit 0 with {len(lines)} stderr lines:\n{text[:2000]}"
    return rc
