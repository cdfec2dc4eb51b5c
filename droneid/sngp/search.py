"""The SNGP search schedule: epoch 0 (two random starts), then epochs of parallel "threads".

Each thread starts from the best population so far, runs its share of generations of (1+1)
local search in compiled chunks, ends with ~100 identity-relinking steps, and replaces the best
population only when strictly better. The threads of one epoch all start from the same
population (as the reference runs them in parallel). They run one after the other, or with
``workers > 1`` (the unconstrained variant) side by side on as many cores (the kernels release the
GIL): every random seed is drawn before the epoch in the order of the sequential schedule, each
thread works on its own population and counters, and the results are compared in thread order
afterwards, so the outcome is bit for bit that of the sequential run. The constrained variant
always runs its threads in turn: they share the archive of non-dominated models, whose contents
depend on the order of insertion.

Early stopping: after every epoch the search scores its best population with ``monitor`` (the
held-out error of ``prune="validation"``, else the search key); when that score has not improved
by the relative ``margin`` for ``window`` generations, the remaining epochs are skipped. The
check draws no random numbers, so a stopped run is the exact prefix of the fixed-budget run.
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from droneid.sngp import kernels as K
from droneid.sngp import population as popmod
from droneid.sngp.population import Population, Problem
from droneid.sngp.selection import rank

#: Scalarisation weights on e_c in the constrained variant, cycled over threads and epochs so
#: that the non-dominated archive spans the front.
WEIGHTS = (0.5, 0.9, 0.7, 0.97, 0.3)
ARCHIVE_SIZE = 64
CHUNK = 1000


@dataclass
class SearchResult:
    best: Population
    archive: list = field(default_factory=list)   # [(e_d, e_c, a, b)], non-dominated
    generations: int = 0          # generations actually run
    budget: int = 0               # generations planned (the cap)
    stopped_early: bool = False
    evaluations: int = 0
    accepted: int = 0
    failed_fits: int = 0
    solves: int = 0               # least-squares refits (generations that changed a feature)
    wall_s: float = 0.0
    cpu_s: float = 0.0


def key(pop: Population, constrained: bool, gamma: float) -> tuple[int, float]:
    """Sort key of a population: :func:`selection.rank` of its model (qualified: unconstrained
    or e_c < gamma)."""
    ed, ec = float(pop.obj[K.O_ED]), float(pop.obj[K.O_EC])
    return rank(ed, ec, (not constrained) or ec < gamma)


def schedule(generations: int, n_epochs: int, n_threads: int) -> list[list[int]]:
    """Generations of each thread of each epoch: ``generations`` split as evenly as possible
    over ``n_epochs x n_threads`` threads (fewer epochs when there are fewer generations)."""
    n_epochs = max(1, min(n_epochs, generations // max(1, n_threads)))
    slots = n_epochs * n_threads
    base, extra = divmod(generations, slots)
    counts = [base + (1 if i < extra else 0) for i in range(slots)]
    return [counts[e * n_threads:(e + 1) * n_threads] for e in range(n_epochs)]


class _Stopper:
    """Tracks the monitored score of the best population; says when it has stalled.

    Improvement: a score below ``(1 - margin)`` times the best score so far (scores are tuples
    compared lexicographically, the last entry relative, the others exactly: see :func:`key`).
    """

    def __init__(self, window: int | None, margin: float):
        self.window = int(window) if window else 0
        self.margin = float(margin)
        self.best = None
        self.since = 0

    def stalled(self, score: tuple, done: int) -> bool:
        if self.best is None or score[:-1] < self.best[:-1] or (
                score[:-1] == self.best[:-1] and score[-1] < self.best[-1] * (1.0 - self.margin)):
            self.best, self.since = score, done
            return False
        return self.window > 0 and done - self.since >= self.window


def run_search(template: Population, problem: Problem, *, generations: int, n_epochs: int,
               n_threads: int, identity_steps: int, gamma: float, rng: np.random.Generator,
               progress=None, early_stop_window: int | None = None, early_stop_margin: float = 0.0,
               monitor=None, workers: int = 1) -> SearchResult:
    """The whole search. ``early_stop_window`` (generations; None or 0: the fixed budget),
    ``early_stop_margin`` (relative) and ``monitor`` (callable(population) -> float, the score
    to watch instead of e_d or e_c in the search key; NaN never improves) control early stopping.
    ``workers``: threads of an epoch run at once (unconstrained only; the result does not depend
    on it, see the module docstring)."""
    t_start = time.perf_counter()
    c_start = time.process_time()
    constrained = bool(template.lay[K.L_MODE])
    P = int(template.lay[K.L_P])
    arch = (np.zeros((ARCHIVE_SIZE, 2)), np.zeros((ARCHIVE_SIZE, P), dtype=np.int64),
            np.zeros((ARCHIVE_SIZE, P), dtype=np.int64), np.zeros(1, dtype=np.int64))
    stats = np.zeros(K.N_STATS, dtype=np.int64)

    def seed() -> int:
        return int(rng.integers(0, 2**31 - 1))

    # epoch 0: two random starts, keep the better
    best = template.copy()
    popmod.load_terminals(best, problem)
    popmod.init(best, problem, seed())
    other = best.copy()
    popmod.init(other, problem, seed())
    for p in (best, other):
        if constrained:
            K._archive_insert(p.obj[K.O_ED], p.obj[K.O_EC], p.a, p.b, *arch)
    if key(other, constrained, gamma) < key(best, constrained, gamma):
        best, other = other, best
    work, cand = other, best.copy()

    plan = schedule(generations, n_epochs, n_threads)
    total = sum(map(sum, plan))
    done = 0
    stopper = _Stopper(early_stop_window, early_stop_margin)
    stopped = False
    relink = identity_steps > 0 and template.lay[K.L_ID] < template.lay[K.L_P]
    side_by_side = workers > 1 and n_threads > 1 and not constrained
    pool = ThreadPoolExecutor(min(workers, n_threads), thread_name_prefix="sngp-search") \
        if side_by_side else None
    works = [work] + [work.copy() for _ in range(n_threads - 1)] if side_by_side else [work]

    def report(done_now: int) -> None:
        if progress is not None:
            progress(done_now, total, f"e_d={best.obj[K.O_ED]:.4g}"
                     + (f" e_c={best.obj[K.O_EC]:.3g}" if constrained else ""))

    def chunk_done(g: int) -> None:     # sequential schedule: progress after every chunk
        nonlocal done
        done += g
        report(done)

    def thread(w: Population, epoch: int, t: int, seeds: list[int], own_stats, per_thread: int,
               chunk_done) -> Population:
        """One thread of an epoch from ``best``: its chunks of generations (``chunk_done(g)``
        after each, when given), then identity relinking, with the seeds drawn for it."""
        weight = WEIGHTS[(epoch * n_threads + t) % len(WEIGHTS)]
        w.copy_from(best)
        left, i = per_thread, 0
        while left > 0:
            g = min(CHUNK, left)
            popmod.run(w, problem, seeds[i], g, False, weight, arch, own_stats)
            i += 1
            left -= g
            if chunk_done is not None:
                chunk_done(g)
        if relink:
            popmod.run(w, problem, seeds[i], identity_steps, True, weight, arch, own_stats)
        return w

    try:
        for epoch, threads in enumerate(plan):
            cand.copy_from(best)
            # the seeds of each thread, in the order the sequential schedule draws them
            seeds = [[seed() for _ in range(-(-n // CHUNK) + relink)] if n else [] for n in threads]
            if side_by_side:
                base = stats.copy()
                own = [stats.copy() for _ in threads]
                futures = [pool.submit(thread, works[t], epoch, t, seeds[t], own[t], n, None)
                           for t, n in enumerate(threads) if n]
                for f in futures:           # in thread order, as the sequential schedule compares
                    w = f.result()
                    if key(w, constrained, gamma) < key(cand, constrained, gamma):
                        cand.copy_from(w)
                for st in own:
                    stats += st - base
                done += sum(threads)
                report(done)
            else:
                for t, per_thread in enumerate(threads):
                    if per_thread:
                        thread(work, epoch, t, seeds[t], stats, per_thread, chunk_done)
                        if key(work, constrained, gamma) < key(cand, constrained, gamma):
                            cand.copy_from(work)
            if key(cand, constrained, gamma) < key(best, constrained, gamma):
                best.copy_from(cand)
            if stopper.window and epoch + 1 < len(plan):
                score = key(best, constrained, gamma)
                if monitor is not None:      # e.g. the held-out error, after the qualification flag
                    score = (score[0], float(monitor(best)))
                if stopper.stalled(score, done):
                    stopped = True
                    if progress is not None:
                        progress(total, total, f"stopped early after {done} generations: no "
                                 f"{100 * stopper.margin:g} % gain in {stopper.window}")
                    break
    finally:
        if pool is not None:
            pool.shutdown()
    n = int(arch[3][0])
    archive = [(float(arch[0][i, 0]), float(arch[0][i, 1]), arch[1][i].copy(), arch[2][i].copy())
               for i in range(n)]
    archive.sort(key=lambda r: r[0])
    return SearchResult(best=best, archive=archive, generations=done, budget=total,
                        stopped_early=stopped,
                        evaluations=int(stats[K.S_EVALS]), accepted=int(stats[K.S_ACCEPT]),
                        failed_fits=int(stats[K.S_FAILED]), solves=int(stats[K.S_SOLVES]),
                        wall_s=time.perf_counter() - t_start,
                        cpu_s=time.process_time() - c_start)
