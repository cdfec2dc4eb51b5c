"""Every command shown in README.md and docs/*.md runs.

A documented command is a line in a fenced shell code block (```` ```sh ````, ``bash``,
``console`` or untagged) that starts with ``droneid `` or ``python -m droneid ``, or a line in any
fenced block that starts with ``$ droneid `` (a prompt before shown output); ``\\`` continues it on
the next line and ``{1..5}`` is expanded as a shell would. Synopses are written as
``usage: droneid ...`` and are not commands. A trailing ``# exit N`` comment documents a non-zero exit code (bad-input examples).

The commands run in document order, in one temporary folder per document (so ``predict`` finds
the ``result.json`` an earlier ``identify`` wrote), through ``droneid.cli.main`` in-process, with a
small search budget substituted. Input paths ``sample_logs/...`` are the shipped sample logs,
``priors/...`` the shipped example TOML files, and
``../shared/real_logs/...`` the shared real logs (documents that use them carry the ``real_logs``
marker and skip where the folder is absent). The fast test only checks that every documented
command parses.
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
PREFIXES = ("droneid ", "python -m droneid ")
SHELL_BLOCKS = {"", "sh", "bash", "shell", "console"}
REAL_PREFIX = "../shared/real_logs/"

#: the search budget each command gets in the test, by command (replaces the documented budget)
BUDGET = {
    "identify": ["--runs", "1", "--generations", "200", "--population", "60", "--jobs", "1"],
    "study": ["--runs", "1", "--generations", "200", "--population", "60", "--jobs", "1"],
    "demo": ["--runs", "1", "--generations", "200", "--population", "60", "--jobs", "1"],
    "fit": ["--generations", "200", "--population", "60"],
    "diagnose": ["--generations", "200"],
}
#: options that set a budget, with the number of values each takes (dropped before BUDGET is added)
BUDGET_OPTIONS = {"--runs": 1, "--generations": 1, "--population": 1, "--jobs": 1, "--quick": 0,
                  "--sngp-generations": 1}


@dataclass(frozen=True)
class DocCommand:
    """One documented command line: where it is written, its words, its documented exit code."""

    document: str
    line: int
    text: str
    argv: tuple[str, ...]
    exit_code: int

    @property
    def uses_real_logs(self) -> bool:
        return any(REAL_PREFIX in a for a in self.argv)

    def __str__(self) -> str:
        return f"{self.document}:{self.line}: {self.text}"


def _expand_braces(word: str) -> list[str]:
    """Shell brace expansion of one numeric range ``a{1..3}b`` -> ``a1b a2b a3b``."""
    m = re.search(r"\{(\d+)\.\.(\d+)\}", word)
    if not m:
        return [word]
    lo, hi = int(m.group(1)), int(m.group(2))
    return [w for i in range(lo, hi + 1)
            for w in _expand_braces(word[:m.start()] + str(i) + word[m.end():])]


def documented_commands(path: Path, root: Path = ROOT) -> list[DocCommand]:
    """The droneid command lines in the fenced code blocks of one Markdown file."""
    commands: list[DocCommand] = []
    lines = path.read_text(encoding="utf-8").splitlines()
    in_block, shell = False, False
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.lstrip().startswith("```"):
            in_block = not in_block
            shell = line.strip()[3:].strip() in SHELL_BLOCKS
            i += 1
            continue
        start = i
        text = line.strip()
        prompt = text.startswith("$ ")
        if prompt:
            text = text[2:]
        if not (in_block and (shell or prompt) and text.startswith(PREFIXES)):
            i += 1
            continue
        while text.endswith("\\") and i + 1 < len(lines):
            i += 1
            text = text[:-1].rstrip() + " " + lines[i].strip()
        i += 1
        exit_match = re.search(r"#\s*exit\s+(\d+)", text)
        words = shlex.split(text, comments=True)
        words = words[3:] if words[:3] == ["python", "-m", "droneid"] else words[1:]
        argv = tuple(w for word in words for w in _expand_braces(word))
        commands.append(DocCommand(path.relative_to(root).as_posix(), start + 1, text, argv,
                                   int(exit_match.group(1)) if exit_match else 0))
    return commands


def _command_name(argv: tuple[str, ...]) -> str | None:
    return next((a for a in argv if not a.startswith("-")), None)


def runnable_argv(cmd: DocCommand) -> list[str]:
    """The documented argv with input paths mapped and the test's budget substituted."""
    argv: list[str] = []
    words = list(cmd.argv)
    while words:
        word = words.pop(0)
        if word in BUDGET_OPTIONS:
            del words[:BUDGET_OPTIONS[word]]
            continue
        if word.startswith("sample_logs/"):
            word = str(SAMPLE_LOGS / word.removeprefix("sample_logs/"))
        elif word.startswith("priors/"):   # the example TOML files shipped in the repo
            word = str(ROOT / word)
        elif word.startswith(REAL_PREFIX):
            word = str(REAL_LOGS / word.removeprefix(REAL_PREFIX))
        argv.append(word)
    name = _command_name(cmd.argv)
    if "-h" not in argv and "--help" not in argv:
        argv += BUDGET.get(name, [])
    if "-q" not in argv and "--quiet" not in argv:
        argv.insert(0, "-q")   # progress lines are not what is tested
    return argv


ALL_COMMANDS = [c for doc in DOCUMENTS for c in documented_commands(doc)]


def test_the_documents_show_commands():
    """The extraction finds the README's worked example and every subcommand is documented."""
    from droneid.cli import build_parser

    names = {_command_name(c.argv) for c in ALL_COMMANDS}
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) <= names, f"commands never shown: {set(sub.choices) - names}"
    assert any(c.document == "README.md" and c.uses_real_logs for c in ALL_COMMANDS)


@pytest.mark.parametrize("cmd", ALL_COMMANDS, ids=str)
def test_documented_command_parses(cmd: DocCommand):
    from droneid.cli import build_parser

    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr):
            args = build_parser().parse_args(runnable_argv(cmd))
    except SystemExit as exc:   # argparse rejected it
        if cmd.exit_code == 2:
            return              # a documented usage error
        pytest.fail(f"{cmd}\ndoes not parse (exit {exc.code}): {stderr.getvalue().strip()}")
    assert args.command == _command_name(cmd.argv)


def _document_params():
    params = []
    for doc in DOCUMENTS:
        cmds = documented_commands(doc)
        if not cmds:
            continue
        marks = [pytest.mark.slow]
        if any(c.uses_real_logs for c in cmds):
            marks.append(pytest.mark.real_logs)
        params.append(pytest.param(doc, cmds, marks=marks, id=doc.relative_to(ROOT).as_posix()))
    return params


@pytest.mark.parametrize(("doc", "cmds"), _document_params())
def test_documented_commands_run(doc: Path, cmds: list[DocCommand], tmp_path, monkeypatch):
    """Each command of the document exits with its documented code (0 unless `# exit N`)."""
    from droneid.cli import main

    if any(c.uses_real_logs for c in cmds) and not REAL_LOGS.is_dir():
        pytest.skip(f"real logs folder {REAL_LOGS} is absent (it lives beside the repo, not in it)")
    monkeypatch.chdir(tmp_path)
    failures = []
    for cmd in cmds:
        out, err = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(runnable_argv(cmd))
        except SystemExit as exc:   # argparse errors and --help
            code = exc.code if isinstance(exc.code, int) else 2
        if code != cmd.exit_code:
            failures.append(f"{cmd}\n  -> exit {code} (documented {cmd.exit_code}): "
                            f"{err.getvalue().strip()[-600:]}")
        elif cmd.exit_code == 2:
            # bad input: one line naming the problem, no traceback
            assert "Traceback" not in err.getvalue(), str(cmd)
            assert len(err.getvalue().strip().splitlines()) == 1, f"{cmd}: {err.getvalue()}"
    assert not failures, "documented commands that fail:\n" + "\n".join(failures)


def test_extraction_rules(tmp_path):
    """Shell blocks and prompts are commands; synopses, output and other languages are not."""
    doc = tmp_path / "x.md"
    doc.write_text("\n".join([
        "```sh",
        "droneid identify ../shared/real_logs/a/run{1..3}.csv \\",
        "    --test sample_logs/b.tlog --quick   # a comment",
        "droneid inspect broken.bin      # exit 2",
        "```",
        "```text",
        "usage: droneid identify TRAIN_LOG...",
        "droneid identify: prior tilt-drag",
        "$ python -m droneid -q diagnose sample_logs/c.tlog",
        "```",
        "```python",
        "droneid = 1",
        "```",
        "droneid inspect outside_a_block.tlog",
    ]), encoding="utf-8")
    cmds = documented_commands(doc, root=tmp_path)
    assert [c.argv for c in cmds] == [
        ("identify", "../shared/real_logs/a/run1.csv", "../shared/real_logs/a/run2.csv",
         "../shared/real_logs/a/run3.csv", "--test", "sample_logs/b.tlog", "--quick"),
        ("inspect", "broken.bin"),
        ("-q", "diagnose", "sample_logs/c.tlog"),
    ]
    assert [c.exit_code for c in cmds] == [0, 2, 0]
    assert [c.line for c in cmds] == [2, 4, 9]
    assert cmds[0].uses_real_logs and not cmds[1].uses_real_logs
    argv = runnable_argv(cmds[0])
    assert "--quick" not in argv and argv[-8:] == BUDGET["identify"]
    assert argv[0] == "-q" and argv[2] == str(REAL_LOGS / "a" / "run1.csv")
    assert str(SAMPLE_LOGS / "b.tlog") in argv
