"""The CLI refuses a target the chosen prior does not model: one line, exit 2, before any work."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_identify_refuses_vz_dot_with_the_tilt_drag_prior():
    log = ROOT / "sample_logs" / "paper_train_eight.tlog"
    assert log.is_file(), "sample_logs/ is part of the repository"
    out = subprocess.run([sys.executable, "-m", "droneid", "identify", str(log), "--prior", "tilt-drag",
                          "--target", "vz_dot", "--quick"], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "has no model of vz_dot" in lines[0] and "Traceback" not in out.stderr
