"""``droneid fit`` on CSV tables."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from droneid.cli import main
from sngp_data import NAMES, flight_data


@pytest.fixture()
def tables(tmp_path):
    X, y = flight_data(n=120, seed=1)
    Xt, yt = flight_data(n=60, seed=9)
    train, test = tmp_path / "train.csv", tmp_path / "test.csv"
    for path, A, b in ((train, X, y), (test, Xt, yt)):
        df = pd.DataFrame(A, columns=NAMES)
        df["vx_dot"] = b
        df["t"] = np.arange(len(b)) * 0.05
        df["flight"] = "f1"
        df.to_csv(path, index=False)
    return train, test


def test_fit_json_line(tables, capsys):
    train, test = tables
    rc = main(["fit", str(train), "--test", str(test), "--target", "vx_dot",
               "--prior", "9.81*cos(yaw)*tan(pitch)/cos(roll)", "--prior", "9.81*sin(yaw)*tan(roll)",
               "--prior=-0.28*vx", "--generations", "300", "--seed", "4", "--json"])
    assert rc == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1
    d = json.loads(out[0])
    assert set(d) == {"equation", "rmse_train", "rmse_test", "constraint_rmse_train",
                      "constraint_rmse_test", "wall_s", "generations", "seed"}
    assert d["rmse_train"] < 1e-9 and d["rmse_test"] < 1e-8
    assert d["seed"] == 4 and d["generations"] == 300
    assert d["constraint_rmse_train"] is None and "P1" in d["equation"]


def test_fit_text_output_inputs_and_save(tables, capsys, tmp_path):
    train, _ = tables
    save = tmp_path / "model.json"
    rc = main(["-q", "fit", str(train), "--target", "vx_dot", "--inputs", "vx,pitch",
               "--generations", "200", "--seed", "1", "--save", str(save)])
    assert rc == 0
    out = capsys.readouterr().out
    assert out.startswith("vx_dot = ") and "rmse train" in out
    from droneid.sngp import SymbolicModel
    model = SymbolicModel.from_dict(json.loads(save.read_text()))
    assert model.input_names == ("vx", "pitch")


@pytest.mark.parametrize("argv, message", [
    (["--target", "vz_dot"], "vz_dot"),
    (["--target", "vx_dot", "--inputs", "vx,pich"], "did you mean 'pitch'"),
    (["--target", "vx_dot", "--prior", "open('x')"], "not allowed"),
    (["--target", "vx_dot", "--depth", "1"], "'max_depth' parameter of FitConfig must be an int >= 2"),
    (["--target", "vx_dot", "--jobs", "0"], "'n_jobs' parameter of FitConfig must be an int >= 1"),
    (["--target", "vx_dot", "--simplify", "-1"], "'simplify_s' parameter of FitConfig"),
])
def test_fit_errors_exit_2(tables, capsys, argv, message):
    train, _ = tables
    rc = main(["fit", str(train), "--generations", "50", *argv])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_fit_bad_csv_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_bytes(b"\x00\x01\x02garbage")
    assert main(["fit", str(bad), "--target", "y"]) == 2
    assert main(["fit", str(tmp_path / "missing.csv"), "--target", "y"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2


def test_fit_with_constraint_file(tables, tmp_path, capsys):
    train, test = tables
    toml = tmp_path / "c.toml"
    toml.write_text('target = "vx_dot"\n'
                    '[[constraint]]\nname = "level"\nrelation = "eq"\nvalue = 0.0\n'
                    'domain = { vx = 0, pitch = 0, roll = ["-pi/15", "pi/15"], yaw = 0 }\n')
    rc = main(["fit", str(train), "--test", str(test), "--target", "vx_dot",
               "--prior", "9.81*cos(yaw)*tan(pitch)/cos(roll) + 9.81*sin(yaw)*tan(roll) - 0.28*vx",
               "--constraints", str(toml), "--generations", "300", "--seed", "2", "--json"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    assert d["constraint_rmse_train"] < 0.05 and d["constraint_rmse_test"] < 0.05


def test_fit_gives_the_same_line_on_one_core_and_on_two(tables, capsys):
    train, test = tables
    lines = []
    for jobs in ("1", "2"):
        assert main(["fit", str(train), "--test", str(test), "--target", "vx_dot", "--generations",
                     "2000", "--population", "80", "--jobs", jobs, "--json"]) == 0
        d = json.loads(capsys.readouterr().out.strip())
        d.pop("wall_s")
        lines.append(d)
    assert lines[0] == lines[1]
