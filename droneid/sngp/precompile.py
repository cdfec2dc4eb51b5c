"""Compile-once support: is the compiled code of the SNGP kernels ready, and compiling it ahead.

numba compiles the kernels on their first call and caches the machine code next to
:mod:`droneid.sngp.kernels` (``cache=True``); later processes load it in well under a second.
:func:`warmup` runs one tiny fit of every variant (plain, with a prior, constrained, held-out
pruning) so that every kernel is compiled and cached; an install step can call it, and a
parallel runner should call it once before starting workers, so that they do not all compile.

How a later process reads that code (lightly, without numba's compiler set-up) is
:func:`droneid.sngp.kernels.load_from_cache_lightly`, applied at a fit's first kernel call.
"""
from __future__ import annotations

import time

import numpy as np

from droneid.core.constraint_samples import ConstraintSamples
from droneid.sngp.estimator import SNGPRegressor
from droneid.sngp.kernels import ENTRY_KERNELS, _target_probe, kernels_ready

__all__ = ["ENTRY_KERNELS", "kernels_ready", "warmup"]


def warmup() -> float:
    """Compile (or load from the cache) every SNGP kernel; returns the seconds it took."""
    t0 = time.perf_counter()
    _target_probe()
    rng = np.random.default_rng(0)
    X = rng.uniform(-1.0, 1.0, (160, 2))
    y = np.sin(X[:, 0]) + 0.5 * X[:, 1] + 0.01 * rng.normal(size=160)
    cs = ConstraintSamples(X=np.zeros((4, 2)), kind=np.zeros(4, dtype=np.int8), bound=np.zeros(4),
                           group=np.zeros(4, dtype=np.int64), input_names=("a", "b"))
    kw = dict(generations=40, population_size=40, n_features=3, n_epochs=1, simplify_s=0,
              identity_steps=5, seed=0, early_stop_window=None)
    SNGPRegressor(prune="validation", **kw).fit(X, y, feature_names=("a", "b"), priors=("b",),
                                                constraints=cs)
    return time.perf_counter() - t0
