"""identify as a real process: it ends without the interpreter's teardown (os._exit, like fit),
so everything it writes must be complete and closed by then (issue 26)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
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


_SERIAL_VS_FORKED = """
import json, sys
import droneid.engine.runner as runner
from droneid.identify.pipeline import IdentifyConfig, identify
from droneid.simulation.simulator import simulate
if sys.argv[1] == "serial":     # every stage split by fork_map runs in this process, in order
    runner.fork_map = lambda fn, shared, items, n_jobs: [fn(shared, item) for item in items]
train = [simulate(path=p, duration_s=15, seed=s).flight for p, s in (("circle", 1), ("eight", 2))]
test = [simulate(path="square", duration_s=12, seed=3).flight]
res = identify(train, test, IdentifyConfig.make(runs=1, generations=100, population_size=60, jobs=2, seed=1))
d = res.to_dict()
d.pop("wall_s")
for t in d["targets"].values():
    for run in t.get("runs", []):
        if run:
            run.pop("wall_s", None)
print(json.dumps(d, sort_keys=False, default=str))
"""


@pytest.mark.slow
def test_the_split_stages_give_what_the_serial_ones_give():
    # the offset search and the scorings of the test flights run on forked workers: the whole
    # result, notes and their order included, must be that of every stage run in one process
    outs = []
    for mode in ("forked", "serial"):
        r = subprocess.run([sys.executable, "-c", _SERIAL_VS_FORKED, mode], capture_output=True, text=True,
                           timeout=600, cwd=ROOT)
        assert r.returncode == 0, r.stderr
        outs.append(r.stdout)
    forked, serial = (json.loads(o) for o in outs)
    assert forked["rotation"] is not None and forked["horizons"]      # every split stage ran
    assert forked == serial and outs[0] == outs[1]
