"""droneid.engine.fit: the table pipeline behind `droneid fit`, from Python (no CLI)."""
import numpy as np
import pandas as pd
import pytest

from droneid.errors import DataError, MissingSignalError
from droneid.engine.fit import FitConfig, fit_table, prepare


def _table(n=200, seed=0):
    rng = np.random.default_rng(seed)
    vx, pitch = rng.uniform(-2, 2, n), rng.uniform(-0.3, 0.3, n)
    return pd.DataFrame({"t": np.arange(n) * 0.05, "vx": vx, "pitch": pitch,
                         "vx_dot": 9.81 * np.tan(pitch) - 0.3 * vx + rng.normal(0, 0.01, n)})


def test_fit_table_recovers_a_planted_law_through_a_prior():
    cfg = FitConfig(target="vx_dot", priors=("9.81*tan(pitch)",), generations=300, population_size=60,
                    n_features=3, seed=1)
    res = fit_table(_table(), cfg, test=_table(seed=2))
    assert res.inputs == ("vx", "pitch")                     # t is never an input by default
    assert res.rmse_train < 0.05 and res.rmse_test < 0.05
    beta = res.estimator.prior_coef_
    assert abs(next(iter(beta.values())) - 1.0) < 0.05       # the prior carries the tilt term
    assert res.to_dict()["rmse_test"] == pytest.approx(res.rmse_test)


def test_prepare_fails_fast_naming_the_table_and_the_column():
    with pytest.raises(MissingSignalError, match="vz_dot"):
        prepare(_table(), FitConfig(target="vz_dot"))
    df = _table(n=5)
    with pytest.raises(DataError, match="cannot support a model"):
        prepare(df, FitConfig(target="vx_dot", n_features=10))


def test_non_finite_rows_are_dropped_and_counted():
    df = _table()
    df.loc[3, "vx"] = np.nan
    df.loc[7, "vx_dot"] = np.inf
    assert prepare(df, FitConfig(target="vx_dot")).dropped_rows == 2
