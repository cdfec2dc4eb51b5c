"""docs/api.md's example runs as written (issue 27: the Python API, documented and tested)."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_the_api_example_runs(monkeypatch, capsys):
    """Every python block of docs/api.md, in order, as one script (about 20 s: one quick identify)."""
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 4, "docs/api.md shows identify, predict, score and horizons"
    monkeypatch.chdir(ROOT)
    namespace = {}
    for i, block in enumerate(blocks):
        exec(compile(block, f"docs/api.md (python block {i + 1})", "exec"), namespace)
    out = capsys.readouterr().out
    assert "vx_dot = " in out and "vz_dot = " in out
    assert "(95 %)" in out and "'final'" in out
    assert re.search(r"beats the empirical model|no better|WORSE|NOT TO BE TRUSTED|no verdict", out)
    assert "['flight', 't_s', 'measured', 'final', 'empirical', 'refit']" in out   # the comment tells the truth
    assert "HorizonErrors(vx=" in out and len(repr(namespace["result"])) < 1000


def test_the_package_top_exports_the_api_lazily():
    import subprocess
    import sys
    code = ("import sys, droneid; assert 'droneid.identify.pipeline' not in sys.modules; "
            "droneid.Identifier; assert 'droneid.identify.pipeline' in sys.modules; print(droneid.read_log.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "droneid.api"
