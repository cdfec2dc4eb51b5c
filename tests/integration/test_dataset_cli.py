"""``droneid dataset`` on the shipped sample logs, and the tilt-drag prior against the sample
logs (planted k_D). Against the real Crazyflie flights: tests/real_logs/test_dataset_real.py."""
import json

import numpy as np
import pandas as pd
import pytest

from _physics import tilt_drag_coefficients
from conftest import SAMPLE_LOGS
from droneid.cli import main
from droneid.dataset.builder import DatasetBuilder


def _sample(name):
    p = SAMPLE_LOGS / name
    assert p.is_file(), f"sample log {p} is missing: sample_logs/ is committed (make sample-logs)"
    return p


def test_cli_exports_the_table(tmp_path, capsys):
    log = _sample("paper_train_eight.tlog")
    out = tmp_path / "table.csv"
    assert main(["dataset", str(log), "--target", "vy_dot", "--ts", "0.1", "-o", str(out)]) == 0
    df = pd.read_csv(out)
    assert list(df.columns) == ["vy", "pitch", "roll", "yaw", "vy_dot", "t", "flight"]
    assert set(df["flight"]) == {"paper_train_eight"}
    assert np.allclose(np.diff(df["t"]), 0.1)
    # the target column is the central difference of the vy column (the default, as identify's)
    vy = df["vy"].to_numpy()
    np.testing.assert_allclose(df["vy_dot"][1:-1], (vy[2:] - vy[:-2]) / 0.2, atol=1e-6)
    err = capsys.readouterr().err
    assert f"{out}: {len(df)} samples of vy_dot" in err and "grid period ts = 0.1 s" in err
    # --method forward: the paper's forward difference
    assert main(["-q", "dataset", str(log), "--target", "vy_dot", "--ts", "0.1", "--method", "forward",
                 "-o", str(out)]) == 0
    df = pd.read_csv(out)
    np.testing.assert_allclose(df["vy_dot"][:-1], np.diff(df["vy"]) / 0.1, atol=1e-6)


def test_cli_options(tmp_path, capsys):
    csv, tlog = _sample("paper_train_eight.csv"), _sample("paper_train_eight.tlog")
    out = tmp_path / "m.csv"
    assert main(["-q", "dataset", str(csv), "--merge", str(tlog), "--inputs", "vx,pitch,roll,yaw,throttle",
                 "--method", "savgol", "--smooth-s", "0.3", "--window", "2:12", "--extras", "z,vz",
                 "--max-samples", "50", "-o", str(out)]) == 0
    assert capsys.readouterr().err == ""
    df = pd.read_csv(out)
    assert list(df.columns) == ["vx", "pitch", "roll", "yaw", "throttle", "z", "vz", "vx_dot", "t", "flight"]
    assert len(df) == 50 and df["t"].min() >= 2.0 and df["t"].max() <= 12.0
    # errors: one line, exit 2
    assert main(["dataset", str(csv), "--inputs", "vx,ptch", "-o", str(out)]) == 2
    assert "did you mean 'pitch'" in capsys.readouterr().err
    assert main(["dataset", str(csv), "--window", "5-9", "-o", str(out)]) == 2
    assert "START:END" in capsys.readouterr().err
    assert main(["dataset", str(csv), "--method", "centrl", "-o", str(out)]) == 2
    assert "did you mean 'central'" in capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["tlog", "mcap", "csv"])
def test_sample_logs_recover_g_scale_and_k_drag(fmt):
    log = _sample(f"paper_train_eight.{fmt}")
    truth = json.loads(log.with_name("paper_train_eight.truth.json").read_text())
    k_true = truth["params"]["k_drag"]
    from parsers import read_flight
    f = read_flight(log)
    for target in ("vx_dot", "vy_dot"):
        beta = tilt_drag_coefficients(DatasetBuilder(method="central").build(f, target, extras=()), target)
        assert beta[0] == pytest.approx(1.0, abs=0.03)       # g-scale, pitch term
        assert beta[1] == pytest.approx(1.0, abs=0.03)       # g-scale, roll term
        assert beta[2] * 0.28 == pytest.approx(k_true, abs=0.02)
        # the paper's forward differences: same g-scale, k_D biased up by the half-step lag
        beta = tilt_drag_coefficients(DatasetBuilder(method="forward").build(f, target, extras=()), target)
        assert beta[0] == pytest.approx(1.0, abs=0.03) and beta[1] == pytest.approx(1.0, abs=0.03)
        assert beta[2] * 0.28 == pytest.approx(k_true, abs=0.07)


@pytest.mark.parametrize("other", ["tlog", "mcap"])
def test_planted_offset_between_sample_mocap_csv_and_autopilot_log(other):
    from parsers import read_flight

    from droneid.dataset.align import estimate_clock_offset, merge_flights
    mocap = read_flight(_sample("paper_test_square.csv"))
    ap = read_flight(_sample(f"paper_test_square.{other}")).shifted(-0.37)
    off = estimate_clock_offset(mocap, ap)
    assert off == pytest.approx(0.37, abs=0.005)  # a tenth of the logs' 0.05 s period
    merged = merge_flights(mocap, ap)
    assert merged["vx"].t[0] == pytest.approx(mocap["x"].t[0], abs=0.005)
