"""Run many independent jobs (SNGP runs) in-process, on a local process pool, or on a Dask cluster.

``run_jobs(fn, jobs, n_jobs=..., scheduler=...)`` calls the top-level, picklable function ``fn``
on every job and returns a :class:`RunOutcome` with the results in job order. A job that raises
an ``Exception`` becomes an error record instead of aborting the batch. Ctrl-C (or a job raising
``KeyboardInterrupt``) stops the batch but keeps every result already finished: the outcome is
flagged ``interrupted`` and unfinished jobs are ``None``.

Backends:

- ``n_jobs == 1`` and no scheduler: in this process, in order (debuggable, no pickling);
- ``n_jobs > 1``: a :mod:`multiprocessing` pool (forked when no other thread is alive, else
  spawned; workers ignore SIGINT, so only this process sees Ctrl-C and can terminate them);
- ``scheduler="tcp://host:port"`` (or a running ``distributed.Client``): Dask distributed.
"""
from __future__ import annotations

import logging
import os
import signal
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from droneid.errors import ConfigError
from droneid.core.lazy import lazy_module

__all__ = ["RunOutcome", "run_jobs", "fork_map", "default_jobs", "startup_message"]

#: the SNGP engine, imported when a command first asks about its kernels (it imports numba, ~0.5 s)
_engine = lazy_module("droneid.sngp")

log = logging.getLogger(__name__)


@dataclass
class RunOutcome:
    """What a batch produced.

    results : one entry per job, in job order; ``None`` where the job did not finish or failed
    errors : {job index: one-line error text} for jobs that raised
    interrupted : True when Ctrl-C (or a job's KeyboardInterrupt) stopped the batch early
    backend : "inprocess", "pool(J)" or "dask(ADDRESS)"
    wall_s : wall time of the whole batch
    """
    results: list
    errors: dict = field(default_factory=dict)
    interrupted: bool = False
    backend: str = "inprocess"
    wall_s: float = 0.0

    @property
    def n_done(self) -> int:
        return sum(r is not None for r in self.results)


def default_jobs() -> int:
    """All cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


#: how long numba takes to compile the SNGP kernels on a first run, for the message below
#: (benchmarks/bench_compile.py: 10-15 s on an idle 2-core machine; more when it is loaded)
_COMPILE_S = "15 s"


def startup_message() -> str:
    """What a progress line says before the first SNGP result arrives.

    numba compiles the SNGP kernels on the first run after an install or an engine change and
    caches them beside :mod:`droneid.sngp.kernels` (or under ``NUMBA_CACHE_DIR``); until then
    the line would sit silent for tens of seconds, so it says so. Later runs load the cache.
    """
    return "starting" if sngp_kernels_cached() else \
        f"compiling SNGP kernels (first run only, ~{_COMPILE_S})…"


def sngp_kernels_cached() -> bool:
    """True when the SNGP kernels are compiled in this process or in numba's cache
    (:func:`droneid.sngp.precompile.kernels_ready`, the engine's own answer)."""
    return _engine.precompile.kernels_ready()


def _call(fn, index, job):
    """Worker side: run one job; exceptions become data, never kill the pool."""
    try:
        return index, "ok", fn(job)
    except KeyboardInterrupt:
        return index, "interrupted", None
    except Exception as exc:  # noqa: BLE001 - reported per job
        return index, "error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=6)}"


def _call_star(args):
    return _call(*args)


def _init_worker(log_level: int):
    """Pool worker: Ctrl-C is the main process's business; log errors only (or everything
    under --debug), since per-run warnings reach the result as data anyway."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    root = logging.getLogger()
    if not root.handlers:
        logging.basicConfig(format="droneid worker: %(levelname)s: %(message)s")
    root.setLevel(log_level if log_level <= logging.DEBUG else max(log_level, logging.ERROR))


def run_jobs(fn: Callable, jobs: Sequence, *, n_jobs: int | None = None, scheduler=None,
             progress: Callable | None = None, label: str = "run",
             connect_timeout_s: float = 20.0) -> RunOutcome:
    """Run ``fn(job)`` for every job; see the module docstring.

    ``progress(done, total, message)`` is called once before the first job (message: what is
    happening, e.g. the first run compiling the SNGP kernels) and after each finished job, also
    failed ones (message: the number of failures so far, or empty).
    """
    jobs = list(jobs)
    if n_jobs is None:
        n_jobs = default_jobs()
    if not isinstance(n_jobs, int) or n_jobs < 1:
        raise ConfigError(f"The 'jobs' parameter must be a positive integer. Got {n_jobs!r} instead.")
    outcome = RunOutcome(results=[None] * len(jobs))
    t0 = time.perf_counter()
    done = 0

    def record(index, status, payload):
        nonlocal done
        done += 1
        if status == "ok":
            outcome.results[index] = payload
        elif status == "error":
            outcome.errors[index] = str(payload).splitlines()[0] if str(payload).strip() else "unknown error"
            log.warning("%s %d failed: %s", label, index + 1, outcome.errors[index])
            log.debug("%s %d: %s", label, index + 1, payload)     # the worker's traceback (--debug)
        else:
            outcome.interrupted = True
            return
        if progress is not None:
            # jobs finish out of order on a pool: naming the job that just finished beside the
            # count ("7/16 ... run 6 done") reads as an off-by-one, so only failures are named
            failed = len(outcome.errors)
            progress(done, len(jobs), f"{failed} failed (last: {label} {index + 1})" if failed else "")

    if progress is not None:
        progress(0, len(jobs), startup_message())
    if not jobs:
        return outcome
    try:
        if scheduler is not None:
            _run_dask(fn, jobs, scheduler, record, outcome, connect_timeout_s)
        elif n_jobs == 1 or len(jobs) == 1:
            outcome.backend = "inprocess"
            for i, job in enumerate(jobs):
                record(*_call(fn, i, job))
                if outcome.interrupted:
                    break
        else:
            _run_pool(fn, jobs, min(n_jobs, len(jobs)), record, outcome)
    except KeyboardInterrupt:
        outcome.interrupted = True
    outcome.wall_s = time.perf_counter() - t0
    if outcome.interrupted:
        log.warning("interrupted: kept %d of %d finished %ss", outcome.n_done, len(jobs), label)
    return outcome


def _can_fork() -> bool:
    """Whether worker processes may be forked from this one: the platform has fork and no other
    thread is alive that could hold a lock in the child (fast, and a caller's script needs no
    ``if __name__ == "__main__":`` guard)."""
    import multiprocessing as mp
    import threading
    return "fork" in mp.get_all_start_methods() and threading.active_count() == 1


#: what :func:`fork_map`'s forked workers were given (set in each worker by the pool's initializer)
_SHARED = None


def _init_forked(log_level: int, shared) -> None:
    global _SHARED
    _init_worker(log_level)
    _SHARED = shared


def _call_shared(args):
    fn, item = args
    try:
        return "ok", fn(_SHARED, item)
    except Exception:   # noqa: BLE001 - the parent reruns the item to raise it as it is
        return "error", None


def fork_map(fn: Callable, shared, items: Sequence, n_jobs: int) -> list:
    """``[fn(shared, item) for item in items]``, on up to ``n_jobs`` forked worker processes
    when this process can fork safely (:func:`_can_fork`), else in this process; the results
    are the same either way, in ``items``' order.

    For a short stage of independent pieces (e.g. identify's offset search): ``shared`` (e.g.
    the flights) reaches the forked workers with the fork itself and is never pickled; items
    and results are. Never spawned: a spawned worker would re-import everything and receive
    ``shared`` pickled, slower than this process alone. An exception in a worker is raised
    here as it is (its type and traceback): the failed item is run again in this process.
    Ctrl-C stops the workers and is raised here."""
    items = list(items)
    n = min(int(n_jobs), len(items))
    if n <= 1 or not _can_fork():
        return [fn(shared, item) for item in items]
    import multiprocessing as mp
    pool = mp.get_context("fork").Pool(n, initializer=_init_forked,
                                       initargs=(logging.getLogger().getEffectiveLevel(), shared))
    try:
        done = pool.map(_call_shared, [(fn, item) for item in items], chunksize=1)
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
    return [res if status == "ok" else fn(shared, item) for (status, res), item in zip(done, items)]


def _run_pool(fn, jobs, n_jobs, record, outcome):
    import multiprocessing as mp
    outcome.backend = f"pool({n_jobs})"
    # fork when it is safe (:func:`_can_fork`), otherwise spawn
    ctx = mp.get_context("fork" if _can_fork() else "spawn")
    pool = ctx.Pool(n_jobs, initializer=_init_worker, initargs=(logging.getLogger().getEffectiveLevel(),))
    try:
        for index, status, payload in pool.imap_unordered(
                _call_star, [(fn, i, j) for i, j in enumerate(jobs)]):
            record(index, status, payload)
            if outcome.interrupted:
                break
    except KeyboardInterrupt:
        outcome.interrupted = True
    finally:
        if outcome.interrupted:
            pool.terminate()
        else:
            pool.close()
        pool.join()


def _run_dask(fn, jobs, scheduler, record, outcome, connect_timeout_s):
    try:
        from distributed import Client, as_completed
    except ImportError as exc:  # pragma: no cover - it is a dependency
        raise ConfigError(f"--scheduler needs the 'distributed' package ({exc})") from None
    own = not isinstance(scheduler, Client)
    try:
        client = Client(scheduler, timeout=f"{connect_timeout_s}s") if own else scheduler
    except OSError as exc:
        raise ConfigError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
    outcome.backend = f"dask({client.scheduler.address})"
    futures = [client.submit(_call, fn, i, job, pure=False, key=f"droneid-{os.getpid()}-{time.time_ns()}-{i}")
               for i, job in enumerate(jobs)]
    try:
        for fut in as_completed(futures):
            if fut.status == "error":
                exc = fut.exception()
                index = futures.index(fut)
                record(index, "error", f"{type(exc).__name__}: {exc}")
            else:
                record(*fut.result())
            if outcome.interrupted:
                break
    except KeyboardInterrupt:
        outcome.interrupted = True
    finally:
        if outcome.interrupted:
            client.cancel(futures)
        if own:
            client.close()
