"""The simulate / sample-logs / demo commands, and the shipped sample logs' reproducibility."""
from __future__ import annotations

import json
import shlex

import pytest

from droneid.cli import main
from droneid.commands.simulate import parse_effect_args
from droneid.errors import ConfigError
from droneid.simulation.sample_logs import FORMATS, SAMPLES, sample_command

from conftest import ROOT, SAMPLE_LOGS

#: what the sample logs' bytes depend on: the simulator's arithmetic (numpy) and each writer's
#: library (the MCAP header names its writer library and version; zstd and lz4 compress chunks)
BYTE_DEPENDENCIES = ("numpy", "pymavlink", "mcap", "mcap-ros2-support", "zstandard", "lz4")


def _require_pinned_versions():
    """The installed versions of :data:`BYTE_DEPENDENCIES` are the ones constraints.txt pins (what
    `make` installs): the committed bytes were written with those. A mismatch names the package
    instead of failing at some byte."""
    from importlib.metadata import version
    pins = dict(line.split("==", 1) for line in (ROOT / "constraints.txt").read_text().splitlines()
                if "==" in line and not line.startswith("#"))
    norm = {k.lower().replace("_", "-"): v.strip() for k, v in pins.items()}
    off = [f"{name} {version(name)} (constraints.txt pins {norm.get(name)})"
           for name in BYTE_DEPENDENCIES if version(name) != norm.get(name)]
    assert not off, ("installed outside `make install`: " + "; ".join(off) +
                     ". Reinstall with `make clean install`, or after `make lock` regenerate the "
                     "samples with `make sample-logs` and commit both")


def test_simulate_command_writes_logs_and_truth(tmp_path, capsys):
    rc = main(["simulate", "--path", "circle", "--duration", "3", "--rate", "20", "--effect", "wind=2,-1.5",
               "--effect", "quadratic_drag=0.1", "--seed", "1", "--format", "tlog,csv", "-o", str(tmp_path),
               "--name", "c1", "--param", "k_drag=0.3"])
    assert rc == 0
    out = capsys.readouterr().out.split()
    assert sorted(p.rsplit("/", 1)[1] for p in out) == ["c1.csv", "c1.tlog", "c1.truth.json"]
    truth = json.loads((tmp_path / "c1.truth.json").read_text())
    assert truth["effects"] == {"wind": {"wx": 2.0, "wy": -1.5}, "quadratic_drag": {"c": 0.1}}
    assert truth["params"]["k_drag"] == 0.3 and truth["seed"] == 1
    assert len(truth["t"]) == len(truth["ax"]) == 61


@pytest.mark.parametrize("argv, msg", [
    (["--effect", "wnd=1"], "did you mean 'wind'"),
    (["--effect", "wind=a"], "expected ID=V1"),
    (["--format", "ulog"], "unknown output format"),
    (["--param", "k_drag"], "KEY=NUMBER"),
])
def test_simulate_command_errors(tmp_path, capsys, argv, msg):
    rc = main(["simulate", "--duration", "1", "-o", str(tmp_path)] + argv)
    assert rc == 2
    assert msg in capsys.readouterr().err


def test_parse_effect_args():
    assert parse_effect_args(["wind=2,-1.5", "battery_sag", "gust=sigma:0.5,tau_s:1"]) == {
        "wind": [2.0, -1.5], "battery_sag": None, "gust": {"sigma": 0.5, "tau_s": 1.0}}
    with pytest.raises(ConfigError):
        parse_effect_args(["gust=1,sigma:2"])


def test_sample_logs_are_small_and_complete():
    assert SAMPLE_LOGS.is_dir(), f"{SAMPLE_LOGS} is missing: sample_logs/ is committed"
    for spec in SAMPLES:
        for f in spec.formats:
            p = SAMPLE_LOGS / f"{spec.name}{FORMATS[f]}"
            assert p.is_file() and p.stat().st_size < 200_000, p   # small enough to ship
        assert (SAMPLE_LOGS / f"{spec.name}.truth.json").is_file()
    assert (SAMPLE_LOGS / "README.md").is_file()


def test_regenerating_a_sample_reproduces_the_committed_bytes(tmp_path):
    """`droneid sample-logs --only NAME` rewrites the shipped files byte for byte."""
    _require_pinned_versions()
    spec = next(s for s in SAMPLES if s.name == "paper_test_square")
    assert main(["-q", "sample-logs", "--out", str(tmp_path), "--only", spec.name]) == 0
    for f in list(spec.formats) + ["truth"]:
        name = f"{spec.name}.truth.json" if f == "truth" else f"{spec.name}{FORMATS[f]}"
        assert (tmp_path / name).read_bytes() == (SAMPLE_LOGS / name).read_bytes(), name


def test_readme_command_reproduces_the_sample(tmp_path):
    """The `droneid simulate` line in sample_logs/README.md writes the same bytes."""
    _require_pinned_versions()
    spec = next(s for s in SAMPLES if s.name == "paper_test_square")
    cmd = sample_command(spec)
    assert cmd in (SAMPLE_LOGS / "README.md").read_text()
    argv = shlex.split(cmd)[1:]
    argv[argv.index("-o") + 1] = str(tmp_path)
    assert main(["-q"] + argv) == 0
    for f in spec.formats:
        name = f"{spec.name}{FORMATS[f]}"
        assert (tmp_path / name).read_bytes() == (SAMPLE_LOGS / name).read_bytes(), name


def test_every_sample_carries_the_rotor_signals():
    from droneid.simulation.simulator import simulate
    for spec in SAMPLES:
        names = simulate(**dict(spec.sim, duration_s=1.0)).flight.names
        for i in range(1, 5):
            assert f"rpm{i}" in names and f"motor{i}" in names, (spec.name, names)
        assert "flatcsv" in spec.formats       # the one CSV that carries them (Motive CSV: pose only)


def test_flat_csv_output_carries_rpm_and_motor_commands(tmp_path):
    import numpy as np

    from droneid.simulation.simulator import simulate
    from parsers import read_flight
    res = simulate(path="circle", duration_s=2.0, rate_hz=20.0, seed=1, rpm_delay_s=0.04)
    from droneid.simulation.sample_logs import save
    (p, _) = save(res, tmp_path, "c", formats=("flatcsv",))
    assert p.name == "c.flat.csv"
    got = read_flight(p)
    for n in ("rpm1", "rpm4", "motor2"):
        np.testing.assert_allclose(got[n].values, res.flight[n].values, rtol=1e-8, atol=1e-9)
