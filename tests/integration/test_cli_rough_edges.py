"""Issue 13's CLI rough edges: option placement, defaults, help, budget, progress, packaging."""
from __future__ import annotations

import argparse
import json
import re
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from droneid.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
FAST = ["--generations", "60", "--population", "40"]


@pytest.fixture()
def table(tmp_path):
    rng = np.random.default_rng(3)
    x, z = rng.normal(size=150), rng.normal(size=150)
    p = tmp_path / "t.csv"
    pd.DataFrame({"vx": x, "pitch": z, "vx_dot": 9.81 * np.tan(z) - 0.3 * x}).to_csv(p, index=False)
    return p


@pytest.mark.parametrize("argv, quiet, debug", [
    (["fit", "t.csv", "--target", "y"], False, False),
    (["-q", "--debug", "fit", "t.csv", "--target", "y"], True, True),
    (["fit", "t.csv", "--target", "y", "-q", "--debug"], True, True),
    (["--debug", "identify", "a.bin", "--quiet"], True, True),
    (["study", "a.bin", "--quiet"], True, False),
])
def test_quiet_and_debug_work_before_and_after_the_command(argv, quiet, debug):
    args = build_parser().parse_args(argv)
    assert (args.quiet, args.debug) == (quiet, debug)


def test_debug_after_the_command_shows_the_traceback(tmp_path):
    with pytest.raises(Exception):
        main(["fit", str(tmp_path / "missing.csv"), "--target", "y", "--debug"])


def test_fit_seed_defaults_to_zero_and_is_printed(table, capsys):
    assert main(["fit", str(table), "--target", "vx_dot", *FAST, "-q"]) == 0
    first = capsys.readouterr().out
    assert "seed 0" in first
    assert main(["fit", str(table), "--target", "vx_dot", *FAST, "-q"]) == 0
    assert capsys.readouterr().out.splitlines()[0] == first.splitlines()[0]  # same equation


def _options(command):
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return [a for a in sub.choices[command]._actions
            if a.option_strings and not isinstance(a, argparse._HelpAction)]


@pytest.mark.parametrize("command", ["fit", "study"])
def test_every_option_of_fit_and_study_has_help_with_its_default(command):
    for a in _options(command):
        assert a.help, a.option_strings
        if a.default not in (None, False, [], argparse.SUPPRESS) or a.dest in ("seed", "save"):
            assert re.search(r"default|paper", a.help), (a.option_strings, a.help)


def test_study_says_its_budget_before_it_starts(tmp_path, capsys):
    rc = main(["study", str(tmp_path / "missing.bin"), "--runs", "3"])
    err = capsys.readouterr().err
    assert rc == 2
    first = err.splitlines()[0]
    assert first.startswith("study: 36 SNGP runs (2 target(s) x 2 scenarios x 3 prior variants x 3 runs)")
    assert "60000 generations x population 500" in first and "--quick" in first
    main(["study", str(tmp_path / "missing.bin"), "--quick"])
    assert "3000 generations x population 200" in capsys.readouterr().err.splitlines()[0]


def test_study_budget_line_is_silent_when_quiet(tmp_path, capsys):
    main(["study", str(tmp_path / "missing.bin"), "-q"])
    assert "SNGP runs (" not in capsys.readouterr().err


def test_progress_says_when_the_kernels_compile(monkeypatch):
    import droneid.engine.runner as runner
    seen = []
    monkeypatch.setattr(runner, "sngp_kernels_cached", lambda: False)
    runner.run_jobs(abs, [1], n_jobs=1, progress=lambda d, t, m="": seen.append((d, m)))
    assert seen[0][0] == 0 and seen[0][1].startswith("compiling SNGP kernels (first run only")
    monkeypatch.setattr(runner, "sngp_kernels_cached", lambda: True)
    seen.clear()
    runner.run_jobs(abs, [1], n_jobs=1, progress=lambda d, t, m="": seen.append((d, m)))
    assert seen[0] == (0, "starting")


def test_progress_says_compiling_when_the_engine_has_no_compiled_kernels(monkeypatch):
    import droneid.engine.runner as runner
    import droneid.sngp.precompile as pre
    monkeypatch.setattr(pre, "kernels_ready", lambda: False)
    assert runner.sngp_kernels_cached() is False and "compiling" in runner.startup_message()
    monkeypatch.setattr(pre, "kernels_ready", lambda: True)
    assert runner.startup_message() == "starting"


def sleepy(x):
    time.sleep(0.6 if x == 0 else 0.05)
    if x == 2:
        raise ValueError("two")
    return x


def test_progress_never_names_a_run_beside_a_count_it_does_not_match():
    from droneid.engine.runner import run_jobs
    seen = []
    out = run_jobs(sleepy, range(4), n_jobs=2, progress=lambda d, t, m="": seen.append((d, t, m)))
    assert [d for d, _, _ in seen] == [0, 1, 2, 3, 4]
    assert out.results[0] == 0 and 2 in out.errors
    for d, t, m in seen[1:]:
        assert m == "" or re.fullmatch(r"1 failed \(last: run \d\)", m), m
    assert any(m == "1 failed (last: run 3)" for _, _, m in seen)


def test_predict_given_a_log_as_the_model_is_one_line(capsys):
    log = ROOT / "sample_logs" / "paper_test_square.tlog"
    assert log.is_file(), f"{log} is missing: sample_logs/ is committed"
    rc = main(["predict", str(log), str(log)])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert f"{log}: is not UTF-8 text" in err


def test_fit_save_to_a_folder_names_the_folder(table, tmp_path, capsys):
    rc = main(["fit", str(table), "--target", "vx_dot", *FAST, "-q", "--save", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2 and f"--save {tmp_path}: is a folder" in err and ".tmp" not in err


def test_atomic_write_errors_name_the_target_not_the_temp_file(tmp_path):
    from droneid.core.io_util import atomic_write_text
    with pytest.raises(IsADirectoryError) as info:
        atomic_write_text(tmp_path, "x")
    assert info.value.filename == str(tmp_path)
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(PermissionError) as info:
            atomic_write_text(ro / "out.json", "x")
        assert info.value.filename == str(ro / "out.json")
    except pytest.fail.Exception:
        pytest.skip("running as a user that ignores folder permissions")
    finally:
        ro.chmod(0o700)


def test_fit_takes_a_prior_from_a_toml_file(table, tmp_path, capsys):
    toml = tmp_path / "p.toml"
    toml.write_text('[prior.tilt]\ntarget = "vx_dot"\nfeatures = ["g*tan(pitch)", "-k*vx"]\n'
                    '[prior.tilt.params]\ng = 9.81\nk = 0.3\n')
    rc = main(["fit", str(table), "--target", "vx_dot", *FAST, "-q", "--prior", f"{toml}:tilt", "--json"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    assert "P1" in d["equation"] and "P2" in d["equation"] and d["rmse_train"] < 1e-6
    assert main(["fit", str(table), "--target", "vx_dot", *FAST, "-q", "--prior", f"{toml}:tlit"]) == 2
    assert "did you mean 'tilt'" in capsys.readouterr().err


def test_fit_hostile_prior_is_one_line_and_fast(table, capsys):
    t0 = time.perf_counter()
    assert main(["fit", str(table), "--target", "vx_dot", *FAST, "--prior", "9**9**9*vx"]) == 2
    assert time.perf_counter() - t0 < 5
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "9**9**9" in err


def test_license_is_an_spdx_string_with_a_setuptools_that_reads_it():
    doc = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert doc["project"]["license"] == "MIT"
    req = next(r for r in doc["build-system"]["requires"] if r.startswith("setuptools"))
    assert int(re.search(r">=(\d+)", req).group(1)) >= 77


def test_a_text_file_that_is_not_json_is_one_line_naming_it(tmp_path, capsys, monkeypatch):
    import droneid.commands.predict as predict_cmd
    monkeypatch.setattr(predict_cmd, "run", lambda args: json.loads(Path(args.model).read_text()))
    bad = tmp_path / "notes.txt"
    bad.write_text("hello, not json\n")
    rc = main(["predict", str(bad), str(bad)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and f"{bad}: is not valid JSON" in err


def test_time_left_ignores_the_one_off_cost_of_the_first_result(monkeypatch):
    import io

    import droneid.commands._common as common
    clock = iter([0.0, 0.0, 40.0, 41.0])  # start, 0/10, 1/10 after compiling, 2/10 one second later
    monkeypatch.setattr(common.time, "perf_counter", lambda: next(clock))
    out = io.StringIO()
    bar = common.ProgressBar("SNGP runs", stream=out)
    for done in (0, 1, 2):
        bar._last_decile = -2  # a non-terminal stream prints per decile: print every call here
        bar(done, 10)
    lines = out.getvalue().splitlines()
    assert "left" not in lines[1]          # one result: no pace yet
    assert "~8 s left" in lines[2]         # 8 runs at 1 s each, not 8 x 20.5 s


@pytest.mark.parametrize("argv, said", [
    (["identify", "a.bin", "--quik"], "droneid identify: error: unrecognized arguments: --quik (did you mean --quick?)"),
    (["predict", "r.json", "a.bin", "--opn-loop", "--zzzz"],
     "unrecognized arguments: --opn-loop --zzzz (--opn-loop: did you mean --open-loop?)"),
    (["identify", "a.bin", "--zzzz"], "droneid identify: error: unrecognized arguments: --zzzz\n"),
    # an abbreviation is refused, not guessed: --horizon was read as --horizons
    (["predict", "r.json", "a.bin", "--horizon", "10"],
     "unrecognized arguments: --horizon 10 (--horizon: did you mean --horizons?)"),
])
def test_an_unknown_option_is_refused_with_the_nearest_one_named(argv, said, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert said in capsys.readouterr().err


def test_a_test_flight_that_is_a_training_flight_is_one_line_exit_2(tmp_path, capsys):
    """The same flight as training and test data (a copy of the file) would test the model on what
    it was fitted to: refused before any work, naming both files."""
    log = ROOT / "sample_logs" / "paper_test_square.tlog"
    copy = tmp_path / "renamed.tlog"
    copy.write_bytes(log.read_bytes())
    assert main(["identify", str(log), "--test", str(copy), "--quick", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "renamed.tlog: this test flight is the same data as the training flight" in err[0], err
