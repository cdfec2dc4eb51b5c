import subprocess
import sys

from droneid.cli import build_parser, main


def test_every_command_registers_a_runner():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    for name, p in sub.choices.items():
        assert p.get_default("func") is not None, name


def test_no_command_is_a_usage_error(capsys):
    assert main([]) == 2


def test_module_entry_point_runs():
    r = subprocess.run([sys.executable, "-m", "droneid", "--version"], capture_output=True, text=True)
    assert r.returncode == 0 and "droneid" in r.stdout
