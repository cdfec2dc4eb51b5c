"""End to end: identify / predict / study / demo through the CLI on simulated logs with planted truth.

The logs are simulated flights shaped like the paper's drone experiment (train: eight, test:
square), written as MAVLink tlogs and read back through the parsers, so the whole chain is
exercised. Budgets are tiny (a few hundred generations) to keep the suite fast; the checks are
on planted structure, not on observed numbers.
"""
from __future__ import annotations

from dataclasses import replace
import json

import numpy as np
import pytest

from droneid.cli import main

SCHEMA_METRICS = ("rmse_train", "rmse_test", "constraint_rmse_test")
TINY = ["--generations", "300", "--population", "100", "--jobs", "1"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """(train eight tlog, test square tlog): planted truth = the paper's model with k_D = 0.4
    (so the empirical model as given, k_D = 0.28, is off and its refit is right)."""
    from droneid.simulation.simulator import simulate
    from parsers.tlog_writer import write_tlog
    d = tmp_path_factory.mktemp("logs")
    train = d / "eight.tlog"
    test = d / "square.tlog"
    write_tlog(simulate(path="eight", duration_s=12, seed=1, k_drag=0.4).flight, train)
    write_tlog(simulate(path="square", duration_s=14, seed=2, k_drag=0.4).flight, test)
    return train, test


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def identified(logs, tmp_path_factory):
    """One CLI identify run shared by the schema / files / predict tests."""
    train, test = logs
    report = tmp_path_factory.mktemp("report")
    code = main(["-q", "identify", str(train), "--test", str(test), "--target", "vx_dot,vy_dot",
                 "--runs", "2", *TINY, "--report", str(report)])
    assert code == 0
    return report


def test_identify_writes_the_documented_schema_and_files(identified):
    names = {p.name for p in identified.iterdir()}
    assert {"result.json", "report.md", "report.html"} <= names
    for t in ("vx_dot", "vy_dot"):
        assert {f"{t}_test_prediction.png", f"{t}_residuals.png", f"{t}_runs.png", f"{t}_pareto.png"} <= names
    doc = json.loads((identified / "result.json").read_text())
    assert {"targets", "config", "provenance", "versions"} <= set(doc)
    for t in ("vx_dot", "vy_dot"):
        tr = doc["targets"][t]
        assert isinstance(tr["equation"], str) and tr["equation"].startswith(f"{t} = ")
        assert isinstance(tr["coefficients"], dict) and isinstance(tr["prior_coefficients"], dict)
        assert len(tr["prior_coefficients"]) == len(tr["prior_features"]) == 2  # rotor-thrust: thrust, drag
        # the ladder, its final model and the models predict and export apply
        assert [r["name"] for r in tr["ladder"]][0] == "empirical" and tr["ladder"][-1]["name"] == "final"
        for r in tr["ladder"]:
            assert {"rmse_train", "rmse_validation", "rmse_test", "constraint_rmse_test", "model"} <= set(r)
        for key in ("final", "empirical_model", "refit_model"):
            assert {"target", "expr", "signals", "delays_s", "equation"} <= set(tr[key])
        assert tr["verdict"].startswith(f"{t}: ")
        for part in ("identified", "empirical", "empirical_refit"):
            assert all(isinstance(tr[part][k], float) for k in SCHEMA_METRICS), part
        assert len(tr["runs"]) == 2
        for r in tr["runs"]:
            assert {"seed", "rmse_train", "rmse_test", "constraint_rmse_test", "wall_s"} <= set(r)
        assert tr["holdout"] is False and tr["constraints"] in ("rotor-thrust", "rotor-thrust+drag-sign")
        assert not {"model", "best_run", "identified_median", "improvement_pct"} & set(tr)   # schema 2
    assert doc["schema"] == "droneid.identify/2"
    assert doc["config"]["prior_features"] == 3 and doc["config"]["constraints"] == "paper"
    # the simulated logs carry motor speeds: auto picks rotor-thrust and says why
    assert doc["config"]["prior_used"] == "rotor-thrust" and "motor speeds" in doc["config"]["prior_reason"]
    assert "delays_s" in doc["config"] and doc["config"]["fitness"]["train"]["ok"]
    assert doc["provenance"]["train"][0]["files"][0].endswith("eight.tlog")
    html = (identified / "report.html").read_text()
    # 5 figures per target (typeset equation, comparison, residual, runs, Pareto) + the multi-step
    # error and trace figures
    assert html.count("data:image/png;base64,") == 12
    assert {f"{t}_equation.png" for t in doc["targets"]} <= names


def test_predict_round_trip_reproduces_the_test_error(identified, logs, capsys):
    _, test = logs
    code, out, _ = run_cli(capsys, "predict", identified / "result.json", test, "--json")
    assert code == 0
    pred = json.loads(out)
    doc = json.loads((identified / "result.json").read_text())
    for t in ("vx_dot", "vy_dot"):
        e = pred["targets"][t]["errors"]["all"]
        assert e["n"] == doc["targets"][t]["n_test"]
        assert e["rmse_identified"] == pytest.approx(doc["targets"][t]["identified"]["rmse_test"], rel=1e-6)
        assert e["rmse_empirical"] == pytest.approx(doc["targets"][t]["empirical"]["rmse_test"], rel=1e-6)
        assert e["rmse_refit"] == pytest.approx(doc["targets"][t]["empirical_refit"]["rmse_test"],
                                                          rel=1e-6)
    code, out, _ = run_cli(capsys, "predict", identified / "result.json", test, "--target", "vx_dot")
    assert code == 0 and "e_d final model" in out and "vy_dot" not in out


def test_identify_terminal_output_and_holdout_note(logs, capsys):
    train, _ = logs
    code, out, _ = run_cli(capsys, "-q", "identify", train, "--target", "vx_dot", "--runs", "1",
                           "--prior", "tilt-drag", "--constraints", "none", "--holdout", "0.3", *TINY)
    assert code == 0
    assert "held out" in out and "time block" in out
    # the verdict comes first, then the equation and the ladder with its method line
    lines = out.splitlines()
    head = lines.index(next(l for l in lines if l.startswith("== vx_dot")))
    assert lines[head + 1].startswith("vx_dot: ") and "empirical model" in lines[head + 1]
    assert "⟨g_cos_yaw_tan_pitch_over_cos_roll⟩" in out
    for label in ("the empirical tilt-drag model as given", "tilt-drag prior refit", "FINAL: ",
                  "e_d validation", "central differences at Ts = 0.05 s"):
        assert label in out


@pytest.mark.slow
def test_constrained_priors_beat_baseline_on_constraints_and_match_refit(logs, tmp_path):
    """Planted truth: the paper's model with k_D = 0.4 (training: eight; test: another eight with
    different noise, i.e. the same flight regime). The constrained + 3 prior variant must satisfy
    the constraints far better than the unconstrained no-prior baseline, and predict no worse than
    the empirical refit (which has the true structure) within 15 %: the identified model contains
    the refit's features, so it can only lose to it by fitting noise with its evolved terms (over
    8 runs of this budget: 0-11 % worse). On the SQUARE test flight the same runs are NOT reliably
    close to the refit: the square reaches |v| = 1.85 m/s where training stopped at 1.45 m/s, and
    evolved terms (powers of vx) extrapolate there; identify says so in a note (checked below)."""
    from droneid.identify.pipeline import IdentifyConfig, identify
    from droneid.simulation.simulator import simulate
    from parsers import read_flight
    train = read_flight(logs[0])
    test = simulate(path="eight", duration_s=12, seed=2, k_drag=0.4).flight
    common = dict(targets=("vx_dot",), runs=2, generations=1500, population_size=150, jobs=1, seed=3,
                  prior="tilt-drag", effects="none", delays="none")  # the paper's setting
    guided = identify([train], [test], IdentifyConfig.make(prior_features=3, constraints="paper", **common))
    base = identify([train], [test], IdentifyConfig.make(prior_features=0, constraints="none", **common))
    g, b = guided.targets["vx_dot"], base.targets["vx_dot"]
    median_ec = lambda tr: float(np.median([r.constraint_rmse_test for r in tr.runs]))  # noqa: E731
    assert median_ec(g) < 0.1 * median_ec(b)
    assert g.identified["constraint_rmse_test"] < 0.05
    assert g.identified["rmse_test"] <= 1.15 * g.empirical_refit["rmse_test"]
    # the empirical model as given has the wrong drag, its refit finds k_D ~ 0.4
    assert g.empirical_refit["rmse_test"] < g.empirical["rmse_test"]
    kd = g.empirical_refit["coefficients"]["minus_kD_vx"] * 0.28  # the term is -0.28 vx
    assert 0.3 < kd < 0.5
    assert not any("training range" in n for n in g.notes)


def test_test_data_outside_the_training_range_are_flagged(logs):
    from droneid.identify.pipeline import IdentifyConfig, prepare_target
    from parsers import read_flight
    cfg = IdentifyConfig.make(targets=("vx_dot",), runs=1, generations=10, population_size=40)
    p = prepare_target([read_flight(logs[0])], [read_flight(logs[1])], "vx_dot", cfg)
    assert any("leave the training range" in n and "vx [" in n for n in p.notes)


@pytest.mark.slow
def test_study_table_shape_and_p_values(logs, tmp_path, capsys):
    train, test = logs
    out_dir = tmp_path / "study"
    code, out, _ = run_cli(capsys, "-q", "study", train, "--test", test, "--target", "vx_dot",
                           "--runs", "2", "--generations", "200", "--population", "80", "--jobs", "1",
                           "--out", out_dir)
    assert code == 0
    from droneid.report.study import study_table
    from droneid.identify.study import StudyResult
    doc = json.loads((out_dir / "study.json").read_text())
    assert StudyResult.from_dict(doc).to_dict() == doc  # study.json reads back to the same document
    header, rows = study_table(doc)
    assert header[:2] == ["scenario", "prior"] and len(header) == 5
    assert len(rows) == 8  # 2 scenarios x 3 prior variants + empirical as given / refit
    variants = doc["targets"]["vx_dot"]["variants"]
    assert set(variants) == {f"{s}/{k}" for s in ("baseline", "constrained") for k in (0, 1, 3)}
    for name, v in variants.items():
        assert v["n_runs"] == 2
        if name.endswith("/0"):
            assert v["p_value_vs_no_prior"] is None
        else:
            assert 0.0 <= v["p_value_vs_no_prior"] <= 1.0
    assert (out_dir / "study.md").is_file() and "p vs none" in out


@pytest.mark.parametrize("argv, message", [
    (["identify", "/nonexistent/log.tlog"], "log.tlog"),
    (["identify", "{train}", "--target", "vx_dott"], "did you mean 'vx_dot'"),
    (["identify", "{train}", "--constraints", "nofile.toml"], "constraints"),
    (["predict", "/nonexistent.json", "{train}"], "nonexistent.json"),
    # a population too small for the problem: said once, before any run (no worker's traceback)
    (["identify", "{train}", "--quick", "--runs", "1", "--population", "20", "--quiet"],
     "'population_size' parameter must be at least"),
])
def test_bad_input_is_one_line_exit_2(logs, capsys, argv, message):
    argv = [a.replace("{train}", str(logs[0])) for a in argv]
    code, _, err = run_cli(capsys, *argv)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_identify_in_a_process_pool_matches_in_process(logs):
    """Runs are seeded from one SeedSequence: the pool gives the same runs as one process."""
    from droneid.identify.pipeline import IdentifyConfig, identify
    from parsers import read_flight
    train, test = read_flight(logs[0]), read_flight(logs[1])
    cfg = dict(targets=("vx_dot",), runs=2, generations=200, population_size=80, seed=5)
    a = identify([train], [test], IdentifyConfig.make(jobs=1, **cfg)).targets["vx_dot"]
    b = identify([train], [test], IdentifyConfig.make(jobs=2, **cfg)).targets["vx_dot"]
    assert [r.seed for r in a.runs] == [r.seed for r in b.runs]
    assert np.allclose([r.rmse_test for r in a.runs], [r.rmse_test for r in b.runs])


@pytest.mark.slow
def test_demo_on_the_shipped_sample_logs_with_a_tiny_budget(tmp_path, capsys):
    from conftest import SAMPLE_LOGS
    # sample_logs/ is committed: its absence is a broken checkout, not a reason to skip
    missing = [n for n in ("paper_train_eight.tlog", "paper_test_square.tlog") if not (SAMPLE_LOGS / n).is_file()]
    assert not missing, f"committed sample log(s) {missing} missing in {SAMPLE_LOGS}"
    code, out, _ = run_cli(capsys, "-q", "demo", "--logs", SAMPLE_LOGS, "--out", tmp_path / "demo", "--runs", "1",
                           "--generations", "100", "--population", "60", "--jobs", "1")
    assert code == 0
    assert "paper_train_eight.tlog" in out and "paper_test_square.tlog" in out
    assert "vx_dot = " in out and "vy_dot = " in out and "FINAL: " in out
    assert (tmp_path / "demo" / "report.html").is_file()


@pytest.mark.slow
def test_ctrl_c_keeps_the_finished_runs(logs, monkeypatch, tmp_path):
    """A KeyboardInterrupt in the third run: the first two are reported, flagged interrupted."""
    import droneid.identify.pipeline as ident
    from parsers import read_flight
    real = ident.run_job

    def flaky(job):
        if job.index == 2:
            raise KeyboardInterrupt
        return real(job)

    monkeypatch.setattr(ident, "run_job", flaky)
    cfg = ident.IdentifyConfig.make(targets=("vx_dot",), runs=4, generations=100, population_size=60, jobs=1)
    res = ident.identify([read_flight(logs[0])], [read_flight(logs[1])], cfg)
    assert res.interrupted and len(res.targets["vx_dot"].runs) == 2
    assert any("interrupted: 2 of 4 runs" in n for n in res.notes)
    from droneid.report import identify as identify_report
    identify_report.write(res.to_dict(), tmp_path)
    assert "interrupted" in identify_report.text(res.to_dict())


@pytest.mark.slow
def test_identify_on_a_dask_local_cluster_matches_in_process(logs):
    import distributed  # a declared dependency: an import failure is a failure, not a skip
    from droneid.identify.pipeline import IdentifyConfig, identify
    from parsers import read_flight
    train, test = read_flight(logs[0]), read_flight(logs[1])
    cfg = dict(targets=("vx_dot",), runs=2, generations=150, population_size=60, seed=4)
    a = identify([train], [test], IdentifyConfig.make(jobs=1, **cfg)).targets["vx_dot"]
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, host="127.0.0.1",
                                  protocol="tcp://", dashboard_address=None) as cluster:
        res = identify([train], [test], IdentifyConfig.make(scheduler=cluster.scheduler_address, **cfg))
    b = res.targets["vx_dot"]
    assert res.backend.startswith("dask(")
    assert np.allclose([r.rmse_test for r in a.runs], [r.rmse_test for r in b.runs])


def test_the_test_flights_never_decide(logs):
    """The same training flights give the same final model, ladder choices and validation errors
    with another test flight or none: test data are reported, never used."""
    from droneid.identify.pipeline import IdentifyConfig, identify
    from droneid.simulation.simulator import simulate
    from parsers import read_flight
    train = read_flight(logs[0])
    other = simulate(path="circle", duration_s=12, seed=5, k_drag=0.6).flight
    cfg = IdentifyConfig.make(runs=2, generations=300, population_size=60, jobs=1, seed=1)
    results = [identify([train], test, cfg) for test in ([read_flight(logs[1])], [other], None)]
    for t in results[0].targets:
        finals = [r.targets[t].final for r in results]
        assert finals[0].expr == finals[1].expr == finals[2].expr
        vals = [[rg.rmse_validation for rg in r.targets[t].ladder] for r in results]
        assert vals[0] == vals[1] == vals[2]
        assert results[0].targets[t].ladder[0].rmse_test != results[1].targets[t].ladder[0].rmse_test
    assert results[0].plan.delays_s == results[1].plan.delays_s == results[2].plan.delays_s


def test_holdout_is_cut_before_any_choice(logs):
    """With --holdout the held-out block is out of the training rows of every rung and of the
    delay choice: training data end where the test block begins, per flight."""
    from droneid.identify.pipeline import IdentifyConfig, identify
    from parsers import read_flight
    cfg = IdentifyConfig.make(targets=("vx_dot",), runs=1, generations=100, population_size=60, jobs=1,
                              test_fraction=0.3)
    res = identify([read_flight(logs[0])], None, cfg).targets["vx_dot"]
    assert res.holdout and 0.25 < res.n_test / (res.n_train + res.n_test) < 0.35
    assert "before any choice" in res.test_data


@pytest.mark.parametrize("planted", [{"quadratic_drag": {"c": 0.3}}, pytest.param(None, marks=pytest.mark.slow)])
def test_identify_folds_the_effect_the_diagnosis_finds(planted):
    """Planted truth inside identify: a quadratic drag the rotor-thrust prior lacks is found on the
    training flight, folded into the prior features (a ladder rung with c near the planted value)
    and kept in the final model; on a control flight no effect is added."""
    from droneid.identify.pipeline import IdentifyConfig, identify
    from droneid.simulation.simulator import simulate
    flight = simulate(path="lissajous", duration_s=60, seed=11, effects=planted).flight
    cfg = IdentifyConfig.make(targets=("vx_dot", "vy_dot"), runs=1, generations=200, population_size=60, jobs=1)
    res = identify([flight], None, cfg)
    for t, tr in res.targets.items():
        rungs = [r.name for r in tr.ladder]
        if planted:
            assert "effect:quadratic_drag" in rungs, (t, rungs, res.notes)
            rung = tr.ladder[rungs.index("effect:quadratic_drag")]
            import re
            c = float(re.search(r"c_D/m = ([0-9.]+)", rung.description).group(1))
            assert c == pytest.approx(0.3, rel=0.1), rung.description
            assert "sqrt(vx**2 + vy**2)" in tr.final.to_dict()["expr"]  # the folded feature is in the final model
            assert rung.rmse_validation < 0.9 * tr.ladder[rungs.index("effect:quadratic_drag") - 1].rmse_validation
        else:
            assert not any(r.startswith("effect:") for r in rungs), (t, rungs, res.notes)


@pytest.mark.slow
def test_the_rotational_choice_runs_beside_the_runs_and_says_what_it_could_not_do():
    """Two simulated training flights with the full state and motor speeds: the rotational job
    runs in the batch, and with two flights no rung can reach the test's first Holm threshold
    (8 flight-regime cells: p >= 2^-8 > 0.01/6), so every axis holds its rate and says so. A log without motor speeds gets a note, not a failure."""
    from droneid.identify.pipeline import IdentifyConfig, identify
    from droneid.simulation.simulator import simulate
    cfg = IdentifyConfig.make(runs=1, generations=100, population_size=60, jobs=1, seed=1)
    train = [simulate(path=p, duration_s=15, seed=s).flight for p, s in (("circle", 1), ("eight", 2))]
    res = identify(train, None, cfg)
    rot = res.rotation
    assert rot is not None and [a.target for a in rot.axes] == ["wx_dot", "wy_dot", "wz_dot"]
    assert all(a.rung == "held" and a.verdict_kind == "no better" for a in rot.axes)
    assert all("with 2 held-out training flight(s) no rung can pass the test" in a.verdict for a in rot.axes)
    assert rot.model is None and rot.dt_s > 0
    assert all(ax["family_size"] == 7 and ax["alpha"] == 0.01 for ax in rot.choice["ladder"])
    assert all(st["cells"] <= 8 and not st["taken"] for ax in rot.choice["ladder"] for st in ax["steps"])
    back = type(res).from_dict(res.to_dict()).rotation
    assert back.to_dict() == rot.to_dict()
    # neither rotor speeds nor per-motor commands (those reach the stage through the motor model:
    # tests/unit/test_rotation_commands.py): no rotational model, and the note says why
    no_rpm = [f.without("rpm1", "rpm2", "rpm3", "rpm4", "motor1", "motor2", "motor3", "motor4") for f in train]
    res = identify(no_rpm, None, replace(cfg, targets=("vx_dot",)))
    assert res.rotation is None
    assert any(n.startswith("rotation not modelled:") and "rotor speeds" in n for n in res.notes)
