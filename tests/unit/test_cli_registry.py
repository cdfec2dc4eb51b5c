"""The command registry: `droneid --help`, `--version` and `droneid CMD --help` import no engine,
numba, sympy or pandas, and a command imports only its own module (issue 26).

Checked through sys.modules in a fresh interpreter (modules whose code ran: one bound lazily and
never used does not count), not through timing."""
from __future__ import annotations

import json
import pkgutil
import subprocess
import sys

import pytest

import droneid.commands
from droneid.cli import build_parser, chosen_command
from droneid.commands import COMMANDS

HEAVY = ("sympy", "numba", "pandas", "scipy", "droneid.sngp", "droneid.engine.fit", "droneid.identify.pipeline",
         "parsers")

_PROBE = """
import json, sys
from droneid.cli import main
try:
    rc = main(sys.argv[1:])
except SystemExit as exc:
    rc = exc.code
# a module bound lazily (importlib.util.LazyLoader) but never used has not run: not loaded
ran = sorted(n for n, m in sys.modules.items() if type(m).__name__ != "_LazyModule")
print(json.dumps({"rc": rc, "modules": ran}), file=sys.stderr)
"""


def _modules_after(*argv: str) -> tuple[int, set[str]]:
    r = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True,
                       timeout=120)
    out = json.loads(r.stderr.strip().splitlines()[-1])
    return out["rc"], set(out["modules"])


def _loaded(modules: set[str], names) -> list[str]:
    return sorted(n for n in names if n in modules or any(m.startswith(n + ".") for m in modules))


def test_every_command_module_is_registered_and_every_entry_has_a_module():
    modules = {f"droneid.commands.{m.name}" for m in pkgutil.iter_modules(droneid.commands.__path__)
               if not m.name.startswith("_")}
    assert {c.module for c in COMMANDS.values()} == modules


def test_each_command_builds_its_own_parser_with_a_runner():
    for name in COMMANDS:
        parser = build_parser(only=[name])
        sub = next(a for a in parser._actions if a.dest == "command")
        assert sub.choices[name].get_default("func") is not None, name
        others = [n for n, p in sub.choices.items() if n != name and p.get_default("func")]
        assert not others, f"{name}: built {others} too"


def test_the_command_is_the_first_argument_that_is_not_an_option():
    assert chosen_command(["-q", "--debug", "fit", "t.csv"]) == "fit"
    assert chosen_command(["--version"]) is None
    assert chosen_command(["no-such-command", "fit"]) is None
    assert chosen_command([]) is None


@pytest.mark.parametrize("argv", [["--help"], ["--version"], []], ids=" ".join)
def test_top_level_help_and_version_import_no_command_module(argv):
    rc, modules = _modules_after(*argv)
    assert rc in (0, 2)
    assert not _loaded(modules, HEAVY)
    assert not [m for m in modules if m.startswith("droneid.commands.")]


@pytest.mark.parametrize("name", list(COMMANDS))
def test_command_help_imports_only_its_module_and_nothing_heavy(name):
    rc, modules = _modules_after(name, "--help")
    assert rc == 0
    assert not _loaded(modules, HEAVY), name
    commands = {m for m in modules if m.startswith("droneid.commands.")}
    assert commands <= {COMMANDS[name].module, "droneid.commands._common",
                        "droneid.commands.identify"}   # study shares identify's budget options


def test_an_unknown_command_is_a_usage_error_naming_the_choices(capsys):
    from droneid.cli import main
    with pytest.raises(SystemExit) as exc:
        main(["fitt"])
    assert exc.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


def _table(path, n=80):
    import numpy as np
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (n, 2))
    y = np.sin(x[:, 0]) + 0.5 * x[:, 1]
    np.savetxt(path, np.c_[x, y], delimiter=",", header="a,b,y", comments="")
    return path


@pytest.mark.slow
def test_fit_as_a_process_writes_everything_before_it_ends_without_teardown(tmp_path):
    """`fit` ends its process without the interpreter's teardown: its output, piped, and its
    saved model are complete, and errors keep their exit code."""
    table = _table(tmp_path / "t.csv")
    model = tmp_path / "m.json"
    r = subprocess.run([sys.executable, "-m", "droneid", "fit", str(table), "--target", "y",
                        "--generations", "200", "--population", "60", "--save", str(model), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("y = ") and lines[-1].endswith("seed 0"), r.stdout
    assert json.loads(model.read_text())["target"] == "y"
    bad = subprocess.run([sys.executable, "-m", "droneid", "fit", str(tmp_path / "missing.csv"),
                          "--target", "y"], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "missing.csv" in bad.stderr


def test_the_engine_and_fits_pipeline_import_without_sympy():
    """Without priors or constraints the search starts before sympy is imported (sympy is then
    imported in a background thread while the search runs)."""
    code = ("import sys, droneid.engine.fit, droneid.sngp.kernels, droneid.sngp.population; "
            "print(sorted(m for m in ('sympy', 'droneid.core.expressions') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stdout + r.stderr
