"""What the docs say of shown output matches the output (issue 40.7): the README's multi-step
table shows every (model, horizon) row the command prints, and docs/use-the-model.md does not call
the README's --quick model identify's defaults."""
from __future__ import annotations

import re

from conftest import ROOT


def _readme_multistep_rows() -> tuple[list[str], list[str]]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text[text.index("== multi-step prediction on the test flights"):]
    block = block[:block.index("\n\n")]
    lines = block.splitlines()
    rows = [ln for ln in lines[3:] if not ln.startswith(("steps of", "After 1 step"))]
    horizons = re.search(r"starts per horizon: (.*)$", block, re.M).group(1)
    return rows, [h.split(":")[0].strip() for h in horizons.split(",")]


def test_readme_multistep_table_shows_every_row():
    """It showed the 4 rows of the 50-step horizon of 12 without saying so."""
    rows, horizons = _readme_multistep_rows()
    models = list(dict.fromkeys(r.split("  ")[0].strip() for r in rows))
    assert len(models) == 4 and len(horizons) == 3
    assert len(rows) == len(models) * len(horizons), rows
    for m in models:
        shown = [r for r in rows if r.startswith(m + " ")]
        assert [re.split(r"\s{2,}", r.strip())[1].split(" ")[0] for r in shown] == horizons


def test_use_the_model_does_not_call_the_quick_model_the_defaults():
    text = (ROOT / "docs" / "use-the-model.md").read_text(encoding="utf-8")
    assert "identify with its defaults on the five squares" not in text
    for m in re.finditer(r"README's model \(([^)]*)\)", text):
        assert "--quick" in m.group(1), m.group(0)
