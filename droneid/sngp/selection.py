"""Which of two models (or runs) is better: the one rule used by the search's acceptance
test, the estimator's final choice from the archive and ``identify``'s choice among runs.

A model *qualifies* when it meets the constraints (its constraint error e_c is below gamma;
every model of an unconstrained search qualifies). Qualified models come first, ordered by
their data error e_d; the others follow, ordered by e_c. NaN ranks last.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TypeVar

__all__ = ["nan_last", "rank", "best_index"]

T = TypeVar("T")


def nan_last(v) -> float:
    """``v`` as a float, with NaN, None and non-numbers mapped to +inf (so they rank last)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        return math.inf
    return v if not math.isnan(v) else math.inf


def rank(e_d, e_c, qualified: bool) -> tuple[int, float]:
    """Sort key of one model: ``(0, e_d)`` when it qualifies, else ``(1, e_c)`` (RMSEs, in the
    target's units). Smaller is better; compare keys as tuples."""
    return (0, nan_last(e_d)) if qualified else (1, nan_last(e_c))


def best_index(items: Sequence[T], e_d: Callable[[T], float], e_c: Callable[[T], float],
               qualified: Callable[[T], bool]) -> int | None:
    """Index of the best item by :func:`rank`; ties go to the lower e_d, then to the earlier
    item. ``None`` items are skipped; None when there is no item."""
    idx = [i for i, it in enumerate(items) if it is not None]
    if not idx:
        return None
    return min(idx, key=lambda i: (*rank(e_d(items[i]), e_c(items[i]), qualified(items[i])),
                                   nan_last(e_d(items[i])), i))
