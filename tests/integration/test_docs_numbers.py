"""Numbers in README.md and docs/*.md come from the commands they show, and stay current (issue 29,
item 7).

**Shown output.** A fenced ``text`` block is the output of a command when
- its first line is ``$ droneid ...`` (the command, then its output), or
- the prose since the previous block says "The output" and the previous shell block holds the
  command (the README's worked example).

Such a command is run as documented (its own budget: the numbers depend on it), in one working
folder shared by every document (so ``predict out/crazyflie/result.json`` finds the result the
README's identify wrote; a command is run once however often it is shown), after the document's
earlier commands. Every line shown must be a line of the output, in the output's order (``...``
marks lines left out; runs of spaces count as one, as tables are aligned over every row). This
file runs the outputs of commands on the shipped sample logs; the ones on the shared real logs
run in tests/real_logs/test_docs_numbers_real.py.

**Tables of numbers** that a cheap deterministic computation makes are checked by recomputing
them: the simulator's residual table in docs/simulator.md (the recipe is stated next to it).

Numbers NOT covered are listed in :data:`UNCOVERED` with the reason (timings, figures of
expensive or real-log benchmarks, hand-picked examples); a new output block must be either run
here or listed there.
"""
from __future__ import annotations

import contextlib
import io
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pytest

from conftest import REAL_LOGS, ROOT, SAMPLE_LOGS

DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
REAL_PREFIX = "../shared/real_logs/"
SHELL = {"", "sh", "bash", "shell", "console"}

#: (document, first line of the shown output) -> why its numbers are not checked by a run
UNCOVERED = {
    ("docs/diagnosis.md", "wind: CV RMSE 1.025 -> 0.6433 (-37.2 %), t = 18.82 over 10 blocks, p = 7.8e-09 < 0.00077 (α = 0.01, Bonferroni over 13), 10/10 blocks better: accepted"):
        "an example of the evidence line's format, not the output of a shown command",
    ("docs/sngp.md", "f(x) = b0 + sum_i b_i * prior_i(x) + sum_j b_j * feature_j(x)"):
        "a formula, not output",
    ("docs/commands.md", "droneid inspect: error: sample_logs/README.md: unrecognised log format: not DataFlash, tlog, ULog, MCAP or CSV"):
        "an error line without numbers (test_docs_commands.py checks its exit code)",
    ("docs/use-the-model.md", "$ droneid export out/crazyflie/result.json --to c -o model.c"):
        "a transcript of several commands with the C code cut mid-expression (test_export.py checks "
        "the exported code against predict)",
}


@dataclass(frozen=True)
class ShownOutput:
    """A command shown in a document with (part of) its output."""
    document: str
    line: int                 # 1-based line of the first output line
    command: tuple[str, ...]  # argv after 'droneid'
    before: tuple[tuple[str, ...], ...]   # the document's earlier commands (run first)
    lines: tuple[str, ...]    # the shown output ('...' = lines left out)

    @property
    def uses_real_logs(self) -> bool:
        return any(REAL_PREFIX in a for cmd in (*self.before, self.command) for a in cmd)

    def __str__(self) -> str:
        return f"{self.document}:{self.line}: droneid {' '.join(self.command)}"


def _argv(text: str) -> tuple[str, ...]:
    words = shlex.split(text, comments=True)
    words = words[3:] if words[:3] == ["python", "-m", "droneid"] else words[1:]
    out = []
    for w in words:
        m = re.search(r"\{(\d+)\.\.(\d+)\}", w)
        out += [w[:m.start()] + str(i) + w[m.end():] for i in range(int(m.group(1)), int(m.group(2)) + 1)] if m else [w]
    return tuple(out)


def _blocks(path: Path):
    """(language, first line number, lines, prose before it) of each fenced block."""
    lines = path.read_text(encoding="utf-8").splitlines()
    prose, i = [], 0
    while i < len(lines):
        if lines[i].lstrip().startswith("```"):
            lang, start, body = lines[i].strip()[3:].strip(), i + 2, []
            i += 1
            while i < len(lines) and not lines[i].lstrip().startswith("```"):
                body.append(lines[i])
                i += 1
            yield lang, start, body, " ".join(prose)
            prose = []
        else:
            prose.append(lines[i])
        i += 1


def _commands(body: list[str]) -> list[tuple[str, ...]]:
    out, i = [], 0
    while i < len(body):
        text = body[i].strip()
        while text.endswith("\\") and i + 1 < len(body):
            i += 1
            text = text[:-1].rstrip() + " " + body[i].strip()
        if text.startswith(("droneid ", "python -m droneid ")):
            out.append(_argv(text))
        i += 1
    return out


def shown_outputs(path: Path) -> list[ShownOutput]:
    found, earlier = [], []
    doc = path.relative_to(ROOT).as_posix()
    for lang, start, body, prose in _blocks(path):
        if lang in SHELL:
            earlier += _commands(body)
            continue
        if lang != "text" or not body:
            continue
        if body[0].startswith("$ droneid ") and sum(ln.startswith("$ ") for ln in body) == 1:
            cmd = _argv(body[0][2:])
            found.append(ShownOutput(doc, start + 1, cmd, tuple(earlier), tuple(body[1:])))
            earlier.append(cmd)
        elif "The output" in prose and earlier:
            found.append(ShownOutput(doc, start, earlier[-1], tuple(earlier[:-1]), tuple(body)))
    return found


ALL_SHOWN = [s for d in DOCUMENTS for s in shown_outputs(d)]


def _local(argv) -> list[str]:
    """Documented paths mapped to the shipped sample logs and the shared real logs."""
    out = []
    for w in argv:
        if w.startswith("sample_logs/"):
            w = str(SAMPLE_LOGS / w.removeprefix("sample_logs/"))
        elif w.startswith(REAL_PREFIX):
            w = str(REAL_LOGS / w.removeprefix(REAL_PREFIX))
        out.append(w)
    return out


_RAN: dict[tuple, tuple[int, str, str]] = {}


def run_documented(argv, folder: Path) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``droneid ARGV`` in ``folder``; each argv once per session."""
    import os

    from droneid.cli import main
    key = (str(folder), tuple(argv))
    if key not in _RAN:
        out, err = io.StringIO(), io.StringIO()
        cwd = os.getcwd()
        os.chdir(folder)
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                try:
                    code = main(_local(argv))
                except SystemExit as exc:
                    code = exc.code if isinstance(exc.code, int) else 2
        finally:
            os.chdir(cwd)
        _RAN[key] = (code, out.getvalue(), err.getvalue())
    return _RAN[key]


def _norm(line: str) -> str:
    return re.sub(r"\s+", " ", line).strip()


def missing_lines(shown: tuple[str, ...], stdout: str, stderr: str) -> list[str]:
    """The shown lines that are not lines of the output in its order (stdout lines in order;
    a line only stderr has, anywhere in stderr)."""
    out = [_norm(x) for x in stdout.splitlines()]
    err = {_norm(x) for x in stderr.splitlines()}
    missing, pos = [], 0
    for line in shown:
        want = _norm(line)
        if not want or want in ("...", "…"):
            continue
        try:
            pos = out.index(want, pos) + 1
        except ValueError:
            if want not in err:
                missing.append(line)
    return missing


def check_shown(shown: ShownOutput, folder: Path) -> None:
    for cmd in shown.before:
        if "-o" in cmd or "--report" in cmd or "--out" in cmd:   # earlier results the command reads
            code, _, err = run_documented(cmd, folder)
            assert code == 0, f"{shown}: the earlier command droneid {' '.join(cmd)} failed: {err[-800:]}"
    code, out, err = run_documented(shown.command, folder)
    assert code == 0, f"{shown}: exit {code}: {err[-800:]}"
    missing = missing_lines(shown.lines, out, err)
    assert not missing, (f"{shown}: {len(missing)} shown line(s) are not what the command prints now "
                         f"(re-run it and update the document):\n" + "\n".join(missing[:15])
                         + "\n--- the command printed:\n" + out[:6000])


@pytest.fixture(scope="session")
def docs_folder(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("docs_run")


# ------------------------------------------------------------------------------------- tests
def test_every_shown_output_is_run_or_listed():
    """Each output block is run (here or in the real-log file) or listed in UNCOVERED."""
    text_blocks = []
    for d in DOCUMENTS:
        for lang, start, body, _ in _blocks(d):
            if lang == "text" and body and not body[0].startswith(("usage:", "{", "make ")):
                text_blocks.append((d.relative_to(ROOT).as_posix(), start, body[0]))
    for doc, start, first in text_blocks:
        runs = any(s.document == doc and start <= s.line <= start + 1 for s in ALL_SHOWN)
        assert runs or (doc, first) in UNCOVERED, \
            f"{doc}:{start}: an output block neither run nor listed in UNCOVERED: {first[:100]}"
    assert len(ALL_SHOWN) >= 3


def test_the_extraction_finds_the_worked_examples():
    docs = {(s.document, s.command[0] if s.command[0] != "-q" else s.command[1]) for s in ALL_SHOWN}
    assert ("README.md", "identify") in docs
    assert ("docs/use-the-model.md", "predict") in docs
    assert ("docs/diagnosis.md", "diagnose") in docs


def test_missing_lines_is_a_real_check():
    out = "a 1\nb  2\nc 3\n"
    assert missing_lines(("a 1", "...", "c 3"), out, "") == []
    assert missing_lines(("b 2",), out, "") == []                 # alignment spaces
    assert missing_lines(("c 3", "a 1"), out, "") == ["a 1"]      # order
    assert missing_lines(("b 2.1",), out, "") == ["b 2.1"]        # a changed number
    assert missing_lines(("note",), out, "note\n") == []          # stderr


@pytest.mark.slow
@pytest.mark.parametrize("shown", [s for s in ALL_SHOWN if not s.uses_real_logs], ids=str)
def test_shown_output_on_sample_logs_is_current(shown, docs_folder):
    check_shown(shown, docs_folder)


# ----------------------------------------------------------------- docs/simulator.md's table
def _simulator_table() -> dict[str, tuple[str, str, str, str]]:
    """effect -> (x, y with noise, x, y noise-free) as printed in docs/simulator.md."""
    text = (ROOT / "docs" / "simulator.md").read_text(encoding="utf-8")
    block = text.split("| effect | with noise | noise-free |", 1)[1].split("\n\n", 1)[0]
    rows = {}
    for line in block.splitlines()[2:]:
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3:
            effect = cells[0].split(" ")[0]
            a, b = (c.split(" ")[0:3:2] for c in cells[1:])
            rows[effect] = (a[0], a[1], b[0], b[1])
    return rows


@pytest.mark.slow
def test_simulator_residual_table_is_current():
    """The recipe stated above the table, recomputed: every number to the digits printed."""
    import numpy as np

    from droneid.dataset.builder import DatasetBuilder
    from droneid.simulation.simulator import simulate
    from priors.registry import get_prior
    rows = _simulator_table()
    assert len(rows) == 10 and "none" in rows
    prior = get_prior("tilt-drag")
    wrong = []
    for effect, printed in rows.items():
        got = []
        for noise in (True, False):
            res = simulate(path="eight", duration_s=24, rate_hz=20, seed=3,
                           effects=None if effect == "none" else {effect: None}, noise=noise)
            for target in ("vx_dot", "vy_dot"):
                ds = DatasetBuilder(ts=0.05, method="forward").build([res.flight], target=target,
                                                                     inputs=prior.inputs(target), extras=())
                pred = prior.evaluate(ds.columns(), target, n_features=1)
                got.append(float(np.sqrt(np.mean((np.ravel(pred) - ds.y) ** 2))))
        text = tuple(f"{v:.3f}" for v in got)
        if text != printed:
            wrong.append(f"{effect}: printed {printed}, computed {text}")
    assert not wrong, "docs/simulator.md's residual table is stale:\n" + "\n".join(wrong)
