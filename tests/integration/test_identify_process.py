"""identify as a real process: it ends without the interpreter's teardown (os._exit, like fit),
so everything it writes must be complete and closed by then (issue 26)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_identify_ends_its_process_with_every_output_complete(tmp_path):
    report = tmp_path / "report"
    r = subprocess.run([sys.executable, "-m", "droneid", "identify", str(ROOT / "sample_logs" / "rotor_climb_eight.csv"),
                        "--runs", "2", "--generations", "300", "--population", "60", "--jobs", "2",
                        "--report", str(report), "--json"],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)              # the whole JSON reached the pipe
    assert set(out["targets"]) >= {"vx_dot", "vy_dot"}
    saved = json.loads((report / "result.json").read_text())
    assert saved["targets"].keys() == out["targets"].keys()
    assert (report / "report.html").read_text().rstrip().endswith("</html>")
    assert (report / "report.md").stat().st_size > 0
    assert not [p.name for p in report.iterdir() if p.name.endswith(".tmp")]   # no half-written file
