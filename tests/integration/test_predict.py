"""``predict`` on the final model: a hand-built result.json over a simulated flight with planted truth.

The flight is simulated with the paper's model and k_D = 0.4 (written as a MAVLink tlog and read
back), so the final model holding the true law must beat the empirical model as given (k_D = 0.28);
the reported RMSE must equal one computed independently from the dataset.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp

from droneid.cli import main
from droneid.fitting.closed_form import IdentifiedModel

TS = 0.05


def _tilt_drag(target: str, k_D: float) -> IdentifiedModel:
    from priors.registry import get_prior
    p = get_prior("tilt-drag", k_D=k_D)
    return IdentifiedModel(target, sp.Add(*[f.expr for f in p.features(target)]), description=f"tilt-drag k_D={k_D}")


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    from droneid.simulation.simulator import simulate
    from parsers.tlog_writer import write_tlog
    path = tmp_path_factory.mktemp("logs") / "square.tlog"
    write_tlog(simulate(path="square", duration_s=14, seed=2, k_drag=0.4).flight, path)
    return path


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    """A result.json as identify writes it: final, empirical_model, refit_model per target."""
    targets = {}
    for t in ("vx_dot", "vy_dot"):
        targets[t] = {"final": _tilt_drag(t, 0.4).to_dict(), "empirical_model": _tilt_drag(t, 0.28).to_dict(),
                      "refit_model": _tilt_drag(t, 0.35).to_dict()}
    path = tmp_path_factory.mktemp("res") / "result.json"
    path.write_text(json.dumps({"schema": "droneid.identify/2", "targets": targets,
                                "config": {"ts": TS, "method": "forward"}}))
    return path


def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_predict_evaluates_the_final_model(result, log, capsys):
    from droneid.dataset.builder import DatasetBuilder
    from droneid.core.numerics import rmse
    from parsers import read_flight
    code, out, _ = run_cli(capsys, "predict", result, log, "--json")
    assert code == 0
    pred = json.loads(out)
    flight = read_flight(log)
    for t in ("vx_dot", "vy_dot"):
        e = pred["targets"][t]["errors"]["all"]
        ds = DatasetBuilder(ts=TS, method="forward").build([flight], target=t, inputs=PAPER[t], extras=())
        cols = ds.columns()
        assert e["n"] == len(ds)
        assert e["rmse_identified"] == pytest.approx(rmse(_tilt_drag(t, 0.4).evaluate(cols), ds.y), rel=1e-9)
        assert e["rmse_empirical"] == pytest.approx(rmse(_tilt_drag(t, 0.28).evaluate(cols), ds.y), rel=1e-9)
        assert e["rmse_refit"] == pytest.approx(rmse(_tilt_drag(t, 0.35).evaluate(cols), ds.y), rel=1e-9)
        # planted truth: the true k_D beats the one given
        assert e["rmse_identified"] < e["rmse_empirical"]
    code, out, _ = run_cli(capsys, "predict", result, log, "--target", "vx_dot")
    assert code == 0 and "e_d final model" in out and "e_d prior refit" in out and "vy_dot" not in out


PAPER = {"vx_dot": ("vx", "pitch", "roll", "yaw"), "vy_dot": ("vy", "pitch", "roll", "yaw")}


def test_predict_horizons_table_json_and_plots(result, log, capsys, tmp_path):
    code, out, _ = run_cli(capsys, "predict", result, log, "--horizons", "1,10,50", "--json")
    assert code == 0
    h = json.loads(out)["horizons"]
    assert set(h) == {"identified", "empirical", "refit", "constant velocity"}
    for m in h:
        assert set(h[m]) == {"1", "10", "50"}
        assert set(h[m]["10"]) == {"vx", "vy", "position"}
        assert h[m]["1"]["vx"] < h[m]["50"]["vx"] and h[m]["1"]["position"] < h[m]["50"]["position"]
    # wrong models drift away with the horizon (the true law levels off at the velocity noise)
    for m in ("empirical", "refit", "constant velocity"):
        assert h[m]["1"]["vx"] < h[m]["10"]["vx"] < h[m]["50"]["vx"]
    # the true law beats the empirical model and the constant-velocity baseline at 0.5 s
    assert h["identified"]["50"]["position"] < h["empirical"]["50"]["position"]
    assert h["identified"]["50"]["vx"] < h["constant velocity"]["50"]["vx"]
    code, out, _ = run_cli(capsys, "predict", result, log, "--horizons", "1,10", "--plot", tmp_path / "plots")
    assert code == 0 and "multi-step prediction" in out and "constant velocity" in out
    assert {p.name for p in (tmp_path / "plots").iterdir()} == {"rollout_error_vs_horizon.png", "rollout_traces.png"}


def test_delayed_inputs_equal_a_shifted_log(result, log):
    """A model reading pitch at t − 0.1 s on the log == the undelayed model on a log whose pitch is
    shifted 0.1 s later, sample by sample where both exist."""
    from droneid.dataset.builder import DatasetBuilder
    from droneid.use.predict import _predict_final
    from parsers import read_flight
    f = read_flight(log)
    m = _tilt_drag("vx_dot", 0.4)
    delayed = IdentifiedModel("vx_dot", m.expr, {"pitch": 0.1})
    b = DatasetBuilder(ts=TS, method="forward")
    ds, preds, notes = _predict_final(b, [f], "vx_dot", {"identified": delayed})
    shifted = f.with_signals(f["pitch"].shifted(0.1))
    ds2, preds2, _ = _predict_final(b, [shifted], "vx_dot", {"identified": m})
    common, i, j = np.intersect1d(np.round(ds.t, 9), np.round(ds2.t, 9), return_indices=True)
    assert common.size > 0.8 * len(ds)
    ok = np.isfinite(preds["identified"][i])
    assert ok.sum() > 0.8 * common.size
    np.testing.assert_allclose(preds["identified"][i][ok], preds2["identified"][j][ok], rtol=1e-9, atol=1e-12)
    from droneid.dataset.builder import resample_signal   # the rows hold pitch read 0.1 s earlier
    np.testing.assert_allclose(ds.column("pitch"), resample_signal(f["pitch"], ds.t - 0.1), rtol=1e-12)
    assert not np.allclose(ds.column("pitch"), resample_signal(f["pitch"], ds.t))
    assert notes == ["identified: pitch read at t − 0.1 s"]


def test_horizons_need_final_models_and_bad_horizons_are_usage_errors(log, tmp_path, capsys):
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"schema": "droneid.identify/1",
                               "targets": {"vx_dot": {"model": {"x": 1}, "inputs": ["vx"]}}}))
    code, _, err = run_cli(capsys, "predict", old, log, "--horizons", "1,10")
    assert code == 2 and "re-run `droneid identify`" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    with pytest.raises(SystemExit) as exc:
        main(["predict", str(old), str(log), "--horizons", "0,x"])
    assert exc.value.code == 2
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"schema": "droneid.identify/2", "targets": {"vx_dot": {"final": {"target": "vx_dot", "expr": "vx +* 2",
                                                                  "signals": ["vx"]}}}}))
    code, _, err = run_cli(capsys, "predict", bad, log)
    assert code == 2 and "bad.json" in err and "targets.vx_dot.final" in err
