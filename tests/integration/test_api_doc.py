"""docs/api.md's example runs as written (issue 27: the Python API, documented and tested)."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_the_api_example_runs(monkeypatch, capsys):
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1, "docs/api.md has one example"
    monkeypatch.chdir(ROOT)
    exec(compile(blocks[0], "docs/api.md", "exec"), {})
    out = capsys.readouterr().out
    assert "vx_dot = " in out and "vz_dot = " in out
    assert "(95 %)" in out and "'final'" in out
    assert re.search(r"beats the empirical model|no better|WORSE|NOT TO BE TRUSTED|no verdict", out)


def test_the_package_top_exports_the_api_lazily():
    import subprocess
    import sys
    code = ("import sys, droneid; assert 'droneid.identify.pipeline' not in sys.modules; "
            "droneid.Identifier; assert 'droneid.identify.pipeline' in sys.modules; print(droneid.read_log.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "droneid.api"
