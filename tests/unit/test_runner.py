"""The job runner: in-process, process pool, Dask LocalCluster; failures and Ctrl-C keep results."""
from __future__ import annotations

import pytest

from droneid.errors import ConfigError
from droneid.engine.runner import run_jobs


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


# -- fork_map: a short stage split over forked workers ------------------------------------------

def _scaled(shared, item):
    if item == "boom":
        raise ConfigError(f"bad item, shared {shared['k']}")
    return shared["f"](item) * shared["k"]


_FORK_MAP = """
import json, os
from droneid.engine.runner import fork_map
def scaled(shared, item):
    return shared["f"](item) * shared["k"]
# a lambda cannot be pickled: the forked workers get it with the fork itself
got = fork_map(scaled, {"f": lambda x: (x, os.getpid()), "k": 1}, list(range(8)), 2)
print(json.dumps({"got": got, "me": os.getpid()}))
"""


def test_fork_map_keeps_the_order_and_never_pickles_what_is_shared():
    # in a fresh process: earlier tests of this one leave threads alive (Dask), and then
    # fork_map rightly stays in-process
    import json
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-c", _FORK_MAP], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    out = json.loads(r.stdout)
    assert [x for x, _ in out["got"]] == list(range(8))
    assert {pid for _, pid in out["got"]} - {out["me"]}       # the work left the calling process


def test_fork_map_raises_a_workers_exception_as_it_is():
    from droneid.engine.runner import fork_map
    with pytest.raises(ConfigError, match="bad item, shared 3"):
        fork_map(_scaled, {"f": lambda x: x, "k": 3}, [1, "boom", 2], 2)


def test_fork_map_stays_in_this_process_when_another_thread_is_alive():
    import os
    import threading

    from droneid.engine.runner import fork_map
    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    try:
        got = fork_map(_scaled, {"f": lambda x: (x, os.getpid()), "k": 1}, [1, 2, 3], 2)
    finally:
        stop.set()
        t.join()
    assert got == [(1, os.getpid()), (2, os.getpid()), (3, os.getpid())]
