"""The job runner: in-process, process pool, Dask LocalCluster; failures and Ctrl-C keep results."""
from __future__ import annotations

import pytest

from droneid.errors import ConfigError
from droneid.runner import run_jobs


def square(x):
    return x * x


def fail_on_three(x):
    if x == 3:
        raise ValueError("three is bad")
    return x


def interrupt_on_three(x):
    if x == 3:
        raise KeyboardInterrupt
    return x


def test_inprocess_keeps_order_and_reports_progress():
    seen = []
    out = run_jobs(square, range(5), n_jobs=1, progress=lambda d, t, m="": seen.append((d, t)))
    assert out.results == [0, 1, 4, 9, 16]
    assert not out.interrupted and out.backend == "inprocess"
    assert seen[0] == (0, 5) and seen[-1] == (5, 5)


def test_process_pool_runs_all_jobs():
    out = run_jobs(square, range(6), n_jobs=2)
    assert out.results == [0, 1, 4, 9, 16, 25]
    assert out.backend == "pool(2)"


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_failing_job_becomes_an_error_record(n_jobs):
    out = run_jobs(fail_on_three, range(5), n_jobs=n_jobs)
    assert out.results == [0, 1, 2, None, 4]
    assert "three is bad" in out.errors[3]
    assert not out.interrupted


def test_interrupt_inprocess_keeps_finished_runs():
    out = run_jobs(interrupt_on_three, range(6), n_jobs=1)
    assert out.interrupted
    assert out.results[:3] == [0, 1, 2] and out.results[3:] == [None, None, None]


def test_interrupt_in_pool_keeps_finished_runs():
    out = run_jobs(interrupt_on_three, range(4), n_jobs=2)
    assert out.interrupted
    assert out.results[3] is None
    assert out.n_done >= 1 and all(r == i for i, r in enumerate(out.results) if r is not None)


def test_bad_jobs_value_is_a_config_error():
    with pytest.raises(ConfigError, match="'jobs'"):
        run_jobs(square, [1], n_jobs=0)


def test_dask_local_cluster_on_loopback():
    import distributed  # a declared dependency: an import failure is a failure, not a skip
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  host="127.0.0.1", protocol="tcp://", dashboard_address=None) as cluster:
        out = run_jobs(square, range(5), scheduler=cluster.scheduler_address)
        assert out.results == [0, 1, 4, 9, 16]
        assert out.backend.startswith("dask(tcp://127.0.0.1")
        out = run_jobs(fail_on_three, range(5), scheduler=cluster.scheduler_address)
        assert out.results == [0, 1, 2, None, 4] and 3 in out.errors


def test_unreachable_scheduler_is_a_config_error():
    with pytest.raises(ConfigError, match="Dask scheduler"):
        run_jobs(square, [1], scheduler="tcp://127.0.0.1:9", connect_timeout_s=1)
