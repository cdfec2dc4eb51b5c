"""Blocked validation, one home: how training rows are cut into contiguous time blocks (or whole
flights) for cross-validation, intervals and block tests, and how a dataset is split into train
and test sets by time block or by flight.

Used by the plan (offset test), the diagnosis, the ladder (rungs, guards, intervals) and the
engine. Blocks are contiguous in time so that autocorrelated samples never sit on both sides of
a split. Times in s.
"""
from __future__ import annotations

import math

import numpy as np

from droneid.dataset.data import Dataset
from droneid.errors import ConfigError, DataError, MissingSignalError, check_choice

__all__ = ["block_ids", "block_in_flight", "validation_blocks", "time_blocks", "n_blocks_for", "split_time_block",
           "split_by_flight"]


def block_ids(t: np.ndarray, flight: np.ndarray, n_blocks: int) -> np.ndarray:
    """One id per (flight, contiguous time block): ``n_blocks`` blocks inside each flight, with
    equal sample counts (so trimmed ground time or gaps leave no block empty); block b of the
    i-th flight (in sorted order) is ``i · n_blocks + b``. Every (flight, block) is its own unit
    of a block test or a bootstrap, so more flights mean more units (block b of every flight
    taken together would leave a test with n_blocks units however many flights there are).
    :func:`block_in_flight` gives b back (a CV fold shared by the flights)."""
    t = np.asarray(t, float)
    flight = np.asarray(flight, int)
    out = np.zeros(t.size, dtype=int)
    for i, f in enumerate(np.unique(flight)):
        idx = np.flatnonzero(flight == f)
        order = idx[np.argsort(t[idx], kind="stable")]
        out[order] = i * n_blocks + np.minimum((n_blocks * np.arange(order.size)) // max(order.size, 1),
                                               n_blocks - 1)
    return out


def block_in_flight(ids: np.ndarray, n_blocks: int) -> np.ndarray:
    """The time block 0..n_blocks-1 inside its flight of each :func:`block_ids` id."""
    return np.asarray(ids, int) % int(n_blocks)


def validation_blocks(t: np.ndarray, flight: np.ndarray) -> tuple[np.ndarray, str]:
    """(block ids, description) for validation on training data: whole flights (leave one
    flight out) when there are at least 3 training flights, so that a term must transfer to a
    flight it was not fitted on; contiguous time blocks inside the flights otherwise."""
    flights = np.unique(flight)
    if flights.size >= 3:
        return np.searchsorted(flights, flight), f"leave-one-flight-out over {flights.size} training flights"
    k = n_blocks_for(t.size)
    return block_ids(t, flight, k), f"{k} contiguous time blocks per training flight"


def time_blocks(t: np.ndarray, flight: np.ndarray, *, family: int = 1, alpha: float = 1.0) -> np.ndarray:
    """Contiguous time blocks of the training flights for intervals and block tests, one unit per
    (flight, block) (:func:`block_ids`): :func:`n_blocks_for` the rows of an average flight, per
    flight (~150 samples a block), and at least enough units in all that a sign-flip test over
    them can reach ``alpha / family`` (its smallest p is 2^-B)."""
    flights = np.unique(flight)
    nf = max(flights.size, 1)
    need = math.ceil(math.log2(max(family, 1) / alpha)) + 1 if alpha < 1.0 else 0
    per = max(n_blocks_for(len(t) // nf), math.ceil(need / nf))
    return block_ids(t, flight, per)


def n_blocks_for(n: int) -> int:
    """Blocks per flight for ``n`` training samples: ~150 samples a block, 8 to 20 blocks."""
    return int(np.clip(n // 150, 8, 20))


def split_time_block(ds: Dataset, test_fraction: float = 0.3, block: str = "last"
                     ) -> tuple[Dataset, Dataset]:
    """Train and test sets by time blocks: in every flight, the ``last`` (or ``middle``)
    ``test_fraction`` of its samples (in time order) is the test set."""
    if isinstance(test_fraction, bool) or not isinstance(test_fraction, (int, float)) \
            or not 0 < test_fraction < 1:
        raise ConfigError(f"The 'test_fraction' parameter must be a number in (0, 1). "
                          f"Got {test_fraction!r} instead.")
    check_choice("block", block, ("last", "middle"), owner="split_time_block")
    test = np.zeros(len(ds), bool)
    for k in np.unique(ds.flight):
        idx = np.flatnonzero(ds.flight == k)
        idx = idx[np.argsort(ds.t[idx], kind="stable")]
        m = int(round(test_fraction * idx.size))
        if m == 0 or m == idx.size:
            continue
        start = idx.size - m if block == "last" else (idx.size - m) // 2
        test[idx[start:start + m]] = True
    if not test.any() or test.all():
        raise DataError(f"cannot split {len(ds)} samples with test_fraction={test_fraction}")
    return ds.subset(~test).noted(f"train: time-block split ({block} {test_fraction:g} is test)"), \
        ds.subset(test).noted(f"test: time-block split ({block} {test_fraction:g} of each flight)")


def split_by_flight(ds: Dataset, test) -> tuple[Dataset, Dataset]:
    """Train and test sets by flight: ``test`` is a source name, an index, or a sequence of them
    (the paper trains on one flight and tests on another)."""
    items = [test] if isinstance(test, (str, int)) else list(test)
    idx = set()
    for it in items:
        if isinstance(it, str):
            if it not in ds.sources:
                raise MissingSignalError(it, ds.sources, where="the dataset's flights")
            idx.add(ds.sources.index(it))
        else:
            if not 0 <= int(it) < len(ds.sources):
                raise ConfigError(f"flight index {it} out of range 0..{len(ds.sources) - 1}")
            idx.add(int(it))
    mask = np.isin(ds.flight, sorted(idx))
    if not mask.any() or mask.all():
        raise DataError("split by flight leaves the train or the test set empty")
    names = ", ".join(ds.sources[i] for i in sorted(idx))
    return ds.subset(~mask).noted(f"train: flights other than {names}"), \
        ds.subset(mask).noted(f"test: flight(s) {names}")
