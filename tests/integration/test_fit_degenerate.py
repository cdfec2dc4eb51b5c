"""``droneid fit`` says when the data cannot support a model instead of printing nonsense."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from droneid.cli import main

FAST = ["--generations", "60", "--population", "40"]


def _table(path, n=200, scale=1.0, seed=0):
    rng = np.random.default_rng(seed)
    x, z = rng.normal(size=n), rng.normal(size=n)
    pd.DataFrame({"vx": x, "pitch": z, "vx_dot": scale * (x + 0.5 * z)}).to_csv(path, index=False)
    return path


@pytest.mark.parametrize("scale, words", [(1e300, "overflow"), (1e-300, "underflow")])
def test_target_beyond_float64_squares_is_refused(tmp_path, capsys, scale, words):
    p = _table(tmp_path / "t.csv", scale=scale)
    with _no_warnings():
        rc = main(["-q", "fit", str(p), "--target", "vx_dot", *FAST])
    err = capsys.readouterr().err
    assert rc == 2 and words in err and "rescale" in err and str(p) in err
    assert "Traceback" not in err and "RuntimeWarning" not in err and len(err.strip().splitlines()) == 1


def test_input_beyond_range_is_refused(tmp_path, capsys):
    p = tmp_path / "t.csv"
    pd.DataFrame({"vx": [1e200, 1.0, 2.0] * 20, "vx_dot": np.arange(60.0)}).to_csv(p, index=False)
    assert main(["-q", "fit", str(p), "--target", "vx_dot", *FAST]) == 2
    assert "input 'vx' reaches 1e+200" in capsys.readouterr().err


def test_too_few_rows_for_the_features_is_refused(tmp_path, capsys):
    p = _table(tmp_path / "t.csv", n=3)
    assert main(["-q", "fit", str(p), "--target", "vx_dot", *FAST]) == 2
    err = capsys.readouterr().err
    assert "3 rows" in err and "11 coefficients" in err and "--features" in err


def test_few_rows_per_coefficient_warns_but_fits(tmp_path, capsys):
    p = _table(tmp_path / "t.csv", n=8)
    assert main(["-q", "fit", str(p), "--target", "vx_dot", "--features", "2", *FAST]) == 0
    cap = capsys.readouterr()
    assert "warning: only 8 rows for up to 3 coefficients" in cap.err
    assert cap.out.startswith("vx_dot = ")


def test_ordinary_table_fits_without_warning(tmp_path, capsys):
    p = _table(tmp_path / "t.csv")
    assert main(["-q", "fit", str(p), "--target", "vx_dot", *FAST, "--json"]) == 0
    cap = capsys.readouterr()
    assert cap.err == "" and json.loads(cap.out)["rmse_train"] < 1e-6


class _no_warnings:
    """Fail if numpy emits a RuntimeWarning inside the block."""

    def __enter__(self):
        import warnings
        self._cm = warnings.catch_warnings()
        self._cm.__enter__()
        warnings.simplefilter("error", RuntimeWarning)

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)
