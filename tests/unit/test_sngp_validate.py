"""The engine's parameter rules have one home, ``SNGPRegressor.validate_params``, which configs
call with their own name as the owner; and the search threads run side by side (``n_jobs``) with
the result of running them one after the other."""
from __future__ import annotations

import json

import numpy as np
import pytest

from droneid.errors import ConfigError
from droneid.sngp import SNGPRegressor

from sngp_data import NAMES, flight_data


def test_validate_params_checks_only_what_is_given_and_returns_it():
    given = {"generations": 500, "max_depth": 3, "prune": "validation"}
    out = SNGPRegressor.validate_params(given)
    assert out == given and out is not given
    assert SNGPRegressor.validate_params({}) == {}
    assert SNGPRegressor.validate_params(SNGPRegressor.default_params()) == SNGPRegressor.default_params()


@pytest.mark.parametrize("params, match", [
    ({"max_depth": 1}, "The 'max_depth' parameter of IdentifyConfig must be an int >= 2. Got 1 instead."),
    ({"generations": 2.5}, "'generations' parameter of IdentifyConfig must be an int >= 1"),
    ({"population_size": True}, "'population_size' parameter"),
    ({"n_jobs": 0}, "'n_jobs' parameter"),
    ({"simplify_s": float("inf")}, "'simplify_s' parameter"),
    ({"gamma": float("nan")}, "'gamma' parameter"),
    ({"prune": "exactly"}, "did you mean 'exact'"),
    ({"functions": "add"}, "'functions' parameter"),
    ({"early_stop_margin": 1.0}, "'early_stop_margin' parameter"),
])
def test_validate_params_names_the_owner_the_parameter_and_the_value(params, match):
    with pytest.raises(ConfigError, match=match.replace("(", r"\(").replace(")", r"\)").replace(".", r"\.")):
        SNGPRegressor.validate_params(params, owner="IdentifyConfig")


def test_validate_params_rejects_an_unknown_name_with_a_suggestion():
    with pytest.raises(ConfigError, match="did you mean 'max_depth'"):
        SNGPRegressor.validate_params({"maxdepth": 3})


def test_depth_one_is_refused_at_fit():
    """At max_depth 1 no operator fits under a feature slot (the slot itself is a level): the
    search could only pick input columns, so the estimator refuses it as identify does."""
    X, y = flight_data(n=40)
    with pytest.raises(ConfigError, match="'max_depth' parameter of SNGPRegressor"):
        SNGPRegressor(max_depth=1, generations=10).fit(X, y)


def test_threads_side_by_side_give_the_sequential_result():
    X, y = flight_data(extra=-0.3)
    kw = dict(generations=3000, population_size=120, n_epochs=3, n_threads=3, seed=4,
              early_stop_window=1000)
    one = SNGPRegressor(n_jobs=1, **kw).fit(X, y, feature_names=NAMES)
    two = SNGPRegressor(n_jobs=2, **kw).fit(X, y, feature_names=NAMES)
    assert one.model_.to_dict() == two.model_.to_dict()
    assert (one.rmse_train_, one.generations_) == (two.rmse_train_, two.generations_)
    same = ("node_evaluations", "accepted", "failed_fits", "least_squares_fits", "generations")
    assert {k: one.search_stats_[k] for k in same} == {k: two.search_stats_[k] for k in same}
    np.testing.assert_array_equal(one.predict(X), two.predict(X))
    # how a fit runs is not part of what it found
    assert "n_jobs" not in two.to_dict()["params"]
    def recorded(m):     # the equation aside: sympy simplifies it under a wall-clock budget
        return json.dumps({k: v for k, v in m.to_dict().items() if k != "equation"}, sort_keys=True)
    assert recorded(one) == recorded(two)
