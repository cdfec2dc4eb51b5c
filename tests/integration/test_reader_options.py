"""Reader options end to end (issue 29, item 9): every command that reads logs takes the same reader
options, identify records the ones its logs were read with (``reader_options`` of result.json), and
predict applies them by default (options given to predict override them).

Done-when of the issue: a model identified with ``--column`` mappings predicts on another log of the
same format, given the same mapping or none. The logs are two simulated flights (a figure eight to
train on, a square to predict) written as flat CSV with every state column renamed to a name droneid
does not know (``est_vx_val``); the same square is also written with droneid's own names and as a
tlog, so that the errors of the renamed log can be checked against a log nobody had to map.
"""
from __future__ import annotations

import csv
import json

import pytest

from droneid.cli import build_parser, main

#: canonical name -> the column name of the user's own CSV format (unknown to droneid's aliases)
RENAMED = {n: f"est_{n}_val" for n in ("x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw")}
COLUMNS = [w for n, c in RENAMED.items() for w in ("--column", f"{n}={c}")]
#: the cheapest identify that still writes final models
BUDGET = ["--prior", "tilt-drag", "--target", "vx_dot", "--runs", "1", "--generations", "200",
          "--population", "60", "--jobs", "1", "--effects", "none", "--delays", "none", "-q"]


def _renamed_copy(src, dst) -> None:
    """The flat CSV ``src`` with only t, the states (renamed) and the flight flags."""
    with open(src, newline="") as f:
        rows = list(csv.reader(f))
    keep = ["t", *RENAMED, "is_armed", "is_flying"]
    idx = [rows[0].index(k) for k in keep]
    with open(dst, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow([RENAMED.get(k, k) for k in keep])
        w.writerows([row[i] for i in idx] for row in rows[1:])


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    from droneid.simulation.simulator import simulate
    from parsers.csv_writer import write_flat_csv
    from parsers.tlog_writer import write_tlog
    d = tmp_path_factory.mktemp("logs")
    out = {}
    for name, path, seed in (("train", "eight", 1), ("next", "square", 2)):
        flight = simulate(path=path, duration_s=20, seed=seed).flight
        write_flat_csv(flight, d / f"{name}_canonical.csv")
        _renamed_copy(d / f"{name}_canonical.csv", d / f"{name}.csv")
        out[name] = d / f"{name}.csv"
        out[f"{name}_canonical"] = d / f"{name}_canonical.csv"
        if name == "next":
            write_tlog(flight, d / "next.tlog")
            out["next_tlog"] = d / "next.tlog"
    return out


def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def result(logs, tmp_path_factory):
    rep = tmp_path_factory.mktemp("rep")
    code = main(["identify", str(logs["train"]), *COLUMNS, *BUDGET, "--report", str(rep)])
    assert code == 0
    return rep / "result.json"


def _errors(out: str) -> dict:
    return json.loads(out)["targets"]["vx_dot"]["errors"]["all"]


@pytest.mark.slow
def test_identify_records_the_mapping(result):
    doc = json.loads(result.read_text(encoding="utf-8"))
    assert doc["reader_options"]["column_map"] == RENAMED
    assert {k for k, v in doc["reader_options"].items() if v is not None} == {"column_map"}


@pytest.mark.slow
def test_the_renamed_log_needs_the_mapping(logs):
    """Without a mapping the user's format cannot be read: what the record is for."""
    from droneid.errors import DroneIdError
    from parsers import read_flight
    with pytest.raises(DroneIdError, match="no recognised signal columns"):
        read_flight(logs["next"])


def test_predict_applies_the_recorded_mapping(result, logs, capsys):
    code, out, err = run_cli(capsys, "predict", result, logs["next"], "--json")
    assert code == 0, err
    none_given = _errors(out)
    assert none_given["n"] > 300
    assert json.loads(out)["reader_options"]["recorded"]["column_map"] == RENAMED
    # the same mapping given again: the same rows and errors
    code, out, err = run_cli(capsys, "predict", result, logs["next"], *COLUMNS, "--json")
    assert code == 0, err
    assert _errors(out) == none_given
    # the same flight under droneid's own names, read without any option, gives the same errors
    # (a result without a record: nothing is applied)
    doc = json.loads(result.read_text(encoding="utf-8"))
    doc.pop("reader_options")
    bare = result.parent / "bare.json"
    bare.write_text(json.dumps(doc), encoding="utf-8")
    code, out, err = run_cli(capsys, "predict", bare, logs["next_canonical"], "--json")
    assert code == 0, err
    canonical = _errors(out)
    assert canonical["n"] == none_given["n"]
    for k in ("rmse_identified", "rmse_empirical", "rmse_refit"):
        assert canonical[k] == pytest.approx(none_given[k], rel=1e-6), k


def test_predict_says_which_options_it_applied(result, logs, capsys):
    code, out, _ = run_cli(capsys, "predict", result, logs["next"])
    assert code == 0
    assert "read with the reader options the model was identified with" in out
    assert "--column vx=est_vx_val" in out


def test_without_the_record_the_renamed_log_is_refused(result, logs, capsys, tmp_path):
    doc = json.loads(result.read_text(encoding="utf-8"))
    doc.pop("reader_options")
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps(doc), encoding="utf-8")
    code, out, err = run_cli(capsys, "predict", bare, logs["next"])
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and str(logs["next"]) in err


def test_given_options_override_the_record(result, logs, capsys):
    code, _, err = run_cli(capsys, "predict", result, logs["next"], "--column", "vx=no_such_column")
    assert code == 2
    assert "no_such_column" in err and "Traceback" not in err
    # the recorded mapping with one entry replaced: the canonical file read by its own names
    own = [w for n in RENAMED for w in ("--column", f"{n}={n}")]
    code, out, err = run_cli(capsys, "predict", result, logs["next_canonical"], *own, "--json")
    assert code == 0, err


def test_a_recorded_mapping_that_does_not_fit_the_log_is_named(result, logs, capsys):
    """The recorded map applied to a CSV of another layout: one line that says the options came
    from the record and how to override them."""
    code, _, err = run_cli(capsys, "predict", result, logs["next_canonical"])
    assert code == 2
    line = err.strip()
    assert len(line.splitlines()) == 1
    assert "est_x_val" in line and "identified with" in line and "override" in line


def test_recorded_options_another_format_does_not_take_are_left_out(result, logs, capsys):
    """A --column map recorded on CSV logs does not stop predict on a tlog of the same flight."""
    code, out, err = run_cli(capsys, "predict", result, logs["next_tlog"], logs["next"], "--json")
    assert code == 0, err
    errors = json.loads(out)["targets"]["vx_dot"]["errors"]
    assert errors["all"]["n"] > 600
    code, out, _ = run_cli(capsys, "predict", result, logs["next_tlog"], logs["next"])
    assert "none of them" in out


@pytest.mark.parametrize("bad, match", [
    ({"column_map": ["vx", "est"]}, "reader_options.column_map must be a map"),
    ({"sysid": "1"}, "reader_options.sysid must be an integer"),
    ({"columns": {}}, "reader_options.columns is not a reader option"),
    ([1], "'reader_options' must be an object"),
])
def test_a_damaged_record_is_one_line(result, logs, capsys, tmp_path, bad, match):
    doc = json.loads(result.read_text(encoding="utf-8"))
    doc["reader_options"] = bad
    p = tmp_path / "damaged.json"
    p.write_text(json.dumps(doc), encoding="utf-8")
    code, _, err = run_cli(capsys, "predict", p, logs["next"])
    assert code == 2
    assert match in err and len(err.strip().splitlines()) == 1


#: every command that reads flight logs
LOG_COMMANDS = ("inspect", "identify", "diagnose", "predict", "dataset", "study")
OPTIONS = ["--format", "csv", "--topic", "pose=/a", "--body", "b1", "--column", "vx=c",
           "--sysid", "3", "--vehicle", "multirotor", "--world-frame", "ned", "--body-frame", "frd",
           "--time-unit", "ms", "--scale", "vx=1/3.6", "--scale", "wz=-1"]


@pytest.mark.parametrize("command", LOG_COMMANDS)
def test_every_command_that_reads_logs_takes_the_reader_options(command):
    positional = {"predict": ["result.json", "a.csv"], "dataset": ["a.csv", "-o", "t.csv"]}
    args = build_parser([command]).parse_args([command, *positional.get(command, ["a.csv"]), *OPTIONS])
    from droneid.commands._common import log_options
    assert log_options(args) == {"format": "csv", "topics": {"pose": "/a"}, "body": "b1",
                                 "column_map": {"vx": "c"}, "sysid": 3, "vehicle": "multirotor",
                                 "world_frame": "ned", "body_frame": "frd", "time_unit": "ms",
                                 "scales": {"vx": "1/3.6", "wz": "-1"}}


def test_export_header_states_the_mapping(result, capsys):
    """Whoever feeds the exported function reads which of their columns each signal came from."""
    code, out, err = run_cli(capsys, "export", result, "--to", "python")
    assert code == 0, err
    header = out.split('"""')[1]
    assert "logs read with --column x=est_x_val" in header and "--column vx=est_vx_val" in header
