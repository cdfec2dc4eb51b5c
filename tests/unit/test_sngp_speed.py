"""SNGP engine speed features: early stopping, bit-for-bit determinism, the compile-once path."""
from __future__ import annotations

import pytest

from droneid.errors import ConfigError
from droneid.sngp import SNGPRegressor

from test_sngp import NAMES, TILT_DRAG_3, flight_data


def _fit(**kw):
    X, y = flight_data(n=200, seed=21, noise=0.05)
    params = dict(generations=20000, population_size=200, seed=4, simplify_s=0)
    params.update(kw)
    return SNGPRegressor(**params).fit(X, y, feature_names=NAMES, priors=TILT_DRAG_3)


def test_early_stop_ends_a_stalled_run_before_the_cap_and_reports_it():
    # the three prior terms are the whole law: nothing left to find after the first epochs
    m = _fit(early_stop_window=2000, early_stop_margin=1e-3)
    assert m.stopped_early_ is True
    assert 2000 <= m.generations_ < 20000
    s = m.search_stats_
    assert s["generations"] == m.generations_ and s["generations_budget"] == 20000
    assert s["early_stop_signal"] == "training error"
    assert m.to_dict()["stopped_early"] is True
    assert m.rmse_train_ < 0.07                      # noise 0.05: the law was found


def test_fixed_budget_when_window_is_none_or_zero():
    for w in (None, 0):
        m = _fit(generations=3000, early_stop_window=w)
        assert m.generations_ == 3000 and m.stopped_early_ is False
        assert m.search_stats_["early_stop_signal"] == "none"


def test_validation_pruning_watches_the_held_out_rows():
    m = _fit(prune="validation", early_stop_window=2000)
    assert m.search_stats_["early_stop_signal"] == "held-out rmse"
    assert m.stopped_early_ and m.generations_ < 20000


@pytest.mark.parametrize("kw", [dict(early_stop_window=2000), dict(early_stop_window=None),
                                dict(early_stop_window=2000, prune="validation")])
def test_same_seed_bit_identical_with_and_without_early_stop(kw):
    a, b = _fit(generations=6000, **kw), _fit(generations=6000, **kw)
    assert a.generations_ == b.generations_
    assert a.equation_ == b.equation_
    assert a.rmse_train_ == b.rmse_train_                      # exact, not approximate
    assert a.model_.to_dict() == b.model_.to_dict()


def test_early_stopped_run_is_a_prefix_of_the_fixed_run():
    """The stopping check draws no random numbers: with the same epochs, the stopped run's
    model is the fixed-budget run's model at that point (checked by running the fixed budget
    for exactly the generations the stopped run used, epochs scaled to match)."""
    stopped = _fit(generations=20000, n_epochs=10, n_threads=2, early_stop_window=2000)
    n_ep = stopped.generations_ // 2000          # each epoch is 2 x 1000 generations
    fixed = _fit(generations=stopped.generations_, n_epochs=n_ep, n_threads=2,
                 early_stop_window=None)
    assert stopped.rmse_train_ == fixed.rmse_train_
    assert stopped.equation_ == fixed.equation_


@pytest.mark.parametrize("params, match", [
    ({"early_stop_window": -1}, "'early_stop_window' parameter"),
    ({"early_stop_window": 2.5}, "'early_stop_window' parameter"),
    ({"early_stop_margin": 1.0}, "'early_stop_margin' parameter"),
    ({"early_stop_margin": -0.1}, "'early_stop_margin' parameter"),
])
def test_early_stop_parameters_validated(params, match):
    X, y = flight_data(n=30)
    with pytest.raises(ConfigError, match=match):
        SNGPRegressor(**params).fit(X, y)


def test_kernels_ready_after_warmup_and_no_compiling_message_then():
    from droneid.sngp import kernels_ready, warmup
    seconds = warmup()
    assert seconds > 0 and kernels_ready()
    messages = []
    X, y = flight_data(n=60)
    SNGPRegressor(generations=50, seed=0, simplify_s=0,
                  progress=lambda d, t, msg="": messages.append(msg)).fit(X, y, feature_names=NAMES)
    assert messages and not any("compiling" in m for m in messages)


def test_compiling_is_announced_when_the_kernels_are_not_ready(monkeypatch):
    from droneid.sngp import estimator
    monkeypatch.setattr(estimator, "kernels_ready", lambda: False)
    messages = []
    X, y = flight_data(n=60)
    SNGPRegressor(generations=50, seed=0, simplify_s=0,
                  progress=lambda d, t, msg="": messages.append(msg)).fit(X, y, feature_names=NAMES)
    assert "compiling the SNGP kernels" in messages[0]


@pytest.mark.slow
def test_fresh_cache_compiles_everything_and_a_second_process_only_loads(tmp_path):
    """First run in a fresh clone: compile time with an empty numba cache, then a cache hit."""
    import os
    import subprocess
    import sys
    code = ("import time; t = time.perf_counter(); import droneid.sngp as s; "
            "r = s.kernels_ready(); s.warmup(); print(r, s.kernels_ready(), time.perf_counter() - t)")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=True).stdout.split() for _ in range(2)]
    assert out[0][:2] == ["False", "True"] and out[1][:2] == ["True", "True"]
    assert float(out[1][2]) < float(out[0][2])


def test_study_keeps_the_papers_fixed_budget(monkeypatch):
    """identify may stop runs early (the estimator's default); the study must not."""
    from droneid.engine import runner
    from droneid.identify.pipeline import IdentifyConfig
    from droneid.simulation.simulator import simulate
    from droneid.identify.study import study

    captured = []

    class _Captured(Exception):
        pass

    def fake_run_jobs(fn, jobs, **kw):
        captured.extend(jobs)
        raise _Captured

    monkeypatch.setattr(runner, "run_jobs", fake_run_jobs)
    train = simulate(path="eight", duration_s=8.0, seed=11).flight
    cfg = IdentifyConfig.make(targets=("vx_dot",), runs=1, generations=50, population_size=40, seed=0)
    with pytest.raises(_Captured):
        study([train], None, cfg)
    assert captured and all(j.engine["early_stop_window"] is None for j in captured)


def test_equation_is_rendered_on_first_use_and_kept():
    X, y = flight_data(n=80)
    m = SNGPRegressor(generations=300, seed=2).fit(X, y, feature_names=NAMES, priors=TILT_DRAG_3)
    assert m._rendered is None                     # fit itself runs no sympy simplification
    eq = m.equation_
    assert isinstance(eq, str) and m._rendered is not None and m.equation_ is eq
    assert set(m.prior_coef_) == {"prior1", "prior2", "prior3"}
    assert m.archive_[0]["equation"] == eq
    with pytest.raises(AttributeError):
        SNGPRegressor().equation_                   # not fitted: NotFittedError is an AttributeError
