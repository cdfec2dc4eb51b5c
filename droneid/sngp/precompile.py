"""Compile-once support: is the compiled code of the SNGP kernels ready, compiling it ahead, and
loading it from numba's cache without numba's compiler set-up.

numba compiles the kernels on their first call and caches the machine code next to
:mod:`droneid.sngp.kernels` (``cache=True``); later processes load it in well under a second.
:func:`warmup` runs one tiny fit of every variant (plain, with a prior, constrained, held-out
pruning) so that every kernel is compiled and cached; an install step can call it, and a
parallel runner should call it once before starting workers, so that they do not all compile.

:func:`load_from_cache_lightly` (installed when :mod:`droneid.sngp` is imported): before it
reads a cached kernel, numba "refreshes" its CPU target, importing and registering its typing
and lowering implementations of all of Python and numpy (numba.np.*, numba.cpython.*, typed
containers, ...: 0.15-0.35 s, a fifth of a ``droneid fit`` process). A kernel read from the
cache is machine code: it needs numba's runtime (NRT) set up and nothing of the compiler. So the
entry kernels' caches read their code after setting up the runtime only; whenever that finds no
usable entry (no cache yet, a changed source, another signature) or fails in any way, numba's
own path runs, with its full set-up, and compiles as always. The code that runs is the cached
code either way: results are bit for bit the same.
"""
from __future__ import annotations

import logging
import time

import numpy as np

from ..constraint_samples import ConstraintSamples
from . import kernels as K
from .estimator import SNGPRegressor
from .kernels import ENTRY_KERNELS, _target_probe, kernels_ready

__all__ = ["ENTRY_KERNELS", "kernels_ready", "warmup", "load_from_cache_lightly"]

log = logging.getLogger(__name__)


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


def load_from_cache_lightly(on: bool = True) -> bool:
    """Have the entry kernels read their cached machine code without numba's target refresh
    (see the module docstring); numba's own loading and compiling remain the fallback. Returns
    whether it is in place (False: this numba lacks the internals it relies on; nothing
    changed). Idempotent. ``on=False`` gives numba its own loading back (kernels already
    loaded stay loaded)."""
    if not on:
        for name in ENTRY_KERNELS:
            vars(getattr(K, name)._cache).pop("load_overload", None)
        return False
    try:
        from numba.core.runtime import rtsys
        caches = [getattr(K, name)._cache for name in ENTRY_KERNELS]
        for cache in caches:    # numba's cache internals this relies on
            cache._load_overload, cache._guard_against_spurious_io_errors, cache.load_overload
        rtsys.initialize    # noqa: B018
    except Exception:   # noqa: BLE001 - another numba: its own loading, as always
        return False
    for cache in caches:
        if "load_overload" not in vars(cache):
            cache.load_overload = _light_loader(cache, rtsys)
    return True


def _light_loader(cache, rtsys):
    """``cache.load_overload`` that reads the code after setting up numba's runtime only; on no
    entry or any failure, the cache's own ``load_overload`` (full target set-up)."""
    full = cache.load_overload

    def load_overload(sig, target_context):
        cres = None
        try:
            rtsys.initialize(target_context)    # the loaded code calls into the runtime
            with cache._guard_against_spurious_io_errors():
                cres = cache._load_overload(sig, target_context)
        except Exception as exc:    # noqa: BLE001 - numba's own path below decides
            log.debug("light kernel loading failed (%s); numba's own loading follows", exc)
            cres = None
        return cres if cres is not None else full(sig, target_context)

    return load_overload


load_from_cache_lightly()
