"""Constraint samples: formal constraints turned into points the SNGP engine evaluates.

Constraint *definitions* (domains, relations) live in :mod:`priors.constraints`; drawing samples
from them gives a :class:`ConstraintSamples`, which the engine caches as extra columns next to
the training data. Violation on a sample: equality ``f(x) - c``; ``le`` ``max(0, f(x) - c)``;
``ge`` ``max(0, c - f(x))``. The constraint error e_c is the RMSE of violations over all samples,
in the target's units.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from droneid.errors import DataError

__all__ = ["ConstraintSamples", "EQ", "LE", "GE", "violations", "constraint_rmse"]

EQ, LE, GE = 0, 1, 2
_KIND = {"eq": EQ, "==": EQ, "le": LE, "<=": LE, "ge": GE, ">=": GE}


@dataclass(frozen=True)
class ConstraintSamples:
    """Sample points of formal constraints.

    X : (m, d) float64 over ``input_names`` (the same columns as the training data)
    kind : (m,) int8, EQ / LE / GE per sample
    bound : (m,) float64, the constant c of each sample's relation (target units)
    group : (m,) int, which constraint (index into ``names``) each sample belongs to
    names : one label per constraint
    """
    X: np.ndarray
    kind: np.ndarray
    bound: np.ndarray
    group: np.ndarray
    input_names: tuple[str, ...]
    names: tuple[str, ...] = ()

    def __post_init__(self):
        X = np.asarray(self.X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != len(self.input_names):
            raise DataError(f"constraint samples X must be (m, {len(self.input_names)}), got {X.shape}")
        m = X.shape[0]
        kind = np.asarray(self.kind, dtype=np.int8).ravel()
        bound = np.asarray(self.bound, dtype=np.float64).ravel()
        group = np.asarray(self.group, dtype=np.int64).ravel()
        if not (kind.size == bound.size == group.size == m):
            raise DataError("constraint samples: X, kind, bound and group lengths differ")
        if m and (kind.min() < EQ or kind.max() > GE):
            raise DataError("constraint samples: kind must be EQ, LE or GE")
        for a in (X, kind, bound, group):
            a.setflags(write=False)
        object.__setattr__(self, "X", X)
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "bound", bound)
        object.__setattr__(self, "group", group)
        object.__setattr__(self, "input_names", tuple(self.input_names))
        object.__setattr__(self, "names", tuple(self.names))

    def __len__(self) -> int:
        return int(self.bound.size)

    @staticmethod
    def kind_code(relation: str) -> int:
        try:
            return _KIND[relation]
        except KeyError:
            raise DataError(f"unknown constraint relation {relation!r}; use eq, le or ge") from None

    def where(self, mask) -> "ConstraintSamples":
        """The samples where ``mask`` (a boolean array over the samples) is true."""
        mask = np.asarray(mask, bool)
        return ConstraintSamples(self.X[mask], self.kind[mask], self.bound[mask], self.group[mask],
                                 self.input_names, self.names)

    def reorder(self, input_names: Sequence[str]) -> "ConstraintSamples":
        """The same samples with columns in the order of ``input_names`` (all must be present)."""
        idx = [self.input_names.index(n) for n in input_names]
        return ConstraintSamples(self.X[:, idx], self.kind, self.bound, self.group,
                                 tuple(input_names), self.names)


def violations(pred: np.ndarray, cs: ConstraintSamples) -> np.ndarray:
    """Per-sample violation of predictions ``pred`` (m,) at ``cs.X``; 0 where satisfied."""
    pred = np.asarray(pred, dtype=np.float64)
    d = pred - cs.bound
    return np.where(cs.kind == EQ, d, np.where(cs.kind == LE, np.maximum(d, 0.0), np.maximum(-d, 0.0)))


def constraint_rmse(pred: np.ndarray, cs: ConstraintSamples) -> float:
    """e_c: the RMSE of the violations (target units); nan for no samples."""
    if len(cs) == 0:
        return float("nan")
    v = violations(pred, cs)
    return float(np.sqrt(np.mean(v * v)))
