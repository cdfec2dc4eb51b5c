"""`droneid inspect`: JSON shape, readable table, one-line errors with exit code 2."""
from __future__ import annotations

import json

import numpy as np

from droneid.cli import main


def _csv(tmp_path):
    p = tmp_path / "f.csv"
    t = np.arange(0, 2, 0.01)
    rows = ["t,x,y,z,is_armed"] + [f"{a:.2f},{np.sin(a):.6f},{a:.6f},1.0,{a > 0.5}" for a in t]
    p.write_text("\n".join(rows) + "\n")
    return p


def test_inspect_json_shape(tmp_path, capsys):
    assert main(["inspect", str(_csv(tmp_path)), "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1
    d = json.loads(out)
    for k in ("format", "duration_s", "signals", "diagnostics", "segments", "events", "notes"):
        assert k in d
    assert d["format"] == "csv" and d["duration_s"] == 1.99
    s = {g["name"]: g for g in d["signals"]}
    assert set(s["x"]) >= {"name", "unit", "rate_hz", "count", "start_s", "end_s", "source"}
    assert s["vx"]["source"].startswith("d/dt") and s["x"]["count"] == 200
    assert d["segments"]["armed"] == [[0.51, 1.99]]


def test_inspect_table(tmp_path, capsys):
    assert main(["inspect", str(_csv(tmp_path))]) == 0
    out = capsys.readouterr().out
    assert "format:    csv" in out and "signal" in out and "rate Hz" in out
    lines = [ln for ln in out.splitlines() if ln.startswith(("x ", "vx "))]
    assert len(lines) == 2 and len({ln.index("m") for ln in lines}) == 1   # aligned unit column
    assert "armed:" in out and "in_flight: none" in out


def test_inspect_errors_are_one_line_exit_2(tmp_path, capsys):
    p = tmp_path / "empty.bin"
    p.write_bytes(b"")
    assert main(["inspect", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "empty" in err and str(p) in err
    assert main(["inspect", str(tmp_path / "missing.tlog")]) == 2
    assert "missing.tlog" in capsys.readouterr().err
    q = tmp_path / "noise.dat"
    q.write_bytes(bytes(range(256)) * 4)
    assert main(["inspect", str(q)]) == 2
    assert "unrecognised log format" in capsys.readouterr().err


def test_inspect_options_parse(tmp_path, capsys):
    p = _csv(tmp_path)
    assert main(["inspect", str(p), "--column", "x=y", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert {g["name"]: g["source"] for g in d["signals"]}["x"] == "y"
    assert main(["inspect", str(p), "--column", "xy"]) == 2
    assert "NAME=VALUE" in capsys.readouterr().err
    assert main(["inspect", str(p), "--body", "b"]) == 2        # --body does not apply to csv
