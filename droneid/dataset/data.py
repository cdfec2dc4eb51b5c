"""Regression data exchanged between stages: the :class:`Dataset`.

Built by :mod:`droneid.dataset.builder` from flights, consumed by the SNGP engine,
identification and diagnosis. Columns use canonical signal names; the target is e.g.
``vx_dot`` (m/s², world ENU).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from droneid.errors import DataError, MissingSignalError

__all__ = ["Dataset"]


@dataclass(frozen=True)
class Dataset:
    """Samples of one regression problem ``target = f(inputs)``.

    Attributes
    ----------
    X : (n, d) float64, one column per name in ``input_names`` (canonical units)
    y : (n,) float64, the target (e.g. ``vx_dot`` in m/s²)
    t : (n,) float64, sample times in seconds from the start of their flight
    input_names : the column names of ``X``
    target_name : the name of ``y``
    flight : (n,) int, index into ``sources`` of the flight each sample came from
    sources : labels of the flights (file stems), in index order
    extra : mapping name -> (n,) float64 of further signals resampled on the same grid that
        are not model inputs (e.g. ``vx`` for a ``vy_dot`` problem, ``z``, ``throttle``);
        the diagnosis uses them to test candidate effects
    notes : human-readable lines on how the data were made (Ts, differentiator, trims)
    screened : {signal: count} of implausible samples and jumps screened out of the signals this
        dataset uses (:mod:`droneid.logs.screening`), summed over its flights; rows that depend on
        them are not in the dataset
    """
    X: np.ndarray
    y: np.ndarray
    t: np.ndarray
    input_names: tuple[str, ...]
    target_name: str
    flight: np.ndarray
    sources: tuple[str, ...] = ()
    extra: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    screened: dict = field(default_factory=dict)

    def __post_init__(self):
        X = np.asarray(self.X, dtype=np.float64)
        y = np.asarray(self.y, dtype=np.float64).ravel()
        t = np.asarray(self.t, dtype=np.float64).ravel()
        fl = np.asarray(self.flight, dtype=np.int64).ravel()
        if X.ndim != 2 or X.shape[0] != y.size or t.size != y.size or fl.size != y.size:
            raise DataError(f"dataset arrays disagree: X {X.shape}, y {y.shape}, t {t.shape}, "
                            f"flight {fl.shape}")
        if X.shape[1] != len(self.input_names):
            raise DataError(f"X has {X.shape[1]} columns but {len(self.input_names)} input names")
        extra = {k: np.asarray(v, dtype=np.float64).ravel() for k, v in dict(self.extra).items()}
        for k, v in extra.items():
            if v.size != y.size:
                raise DataError(f"extra column '{k}' has {v.size} samples, expected {y.size}")
        for a in (X, y, t, fl, *extra.values()):
            a.setflags(write=False)
        object.__setattr__(self, "X", X)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "flight", fl)
        object.__setattr__(self, "input_names", tuple(self.input_names))
        object.__setattr__(self, "sources", tuple(self.sources))
        object.__setattr__(self, "extra", extra)
        object.__setattr__(self, "notes", tuple(self.notes))
        object.__setattr__(self, "screened", {str(k): int(v) for k, v in dict(self.screened).items()})

    def __len__(self) -> int:
        return int(self.y.size)

    def column(self, name: str) -> np.ndarray:
        """An input, the target, ``t``, or an extra column by name."""
        if name in self.input_names:
            return self.X[:, self.input_names.index(name)]
        if name == self.target_name:
            return self.y
        if name == "t":
            return self.t
        if name in self.extra:
            return self.extra[name]
        raise MissingSignalError(name, [*self.input_names, self.target_name, *self.extra],
                                 where=f"the {self.target_name} dataset")

    def columns(self) -> dict[str, np.ndarray]:
        """Every named column (inputs, extras, target, t) as a dict of arrays."""
        out = {n: self.X[:, i] for i, n in enumerate(self.input_names)}
        out.update(self.extra)
        out[self.target_name] = self.y
        out["t"] = self.t
        return out

    def noted(self, note: str) -> "Dataset":
        """The same rows with ``note`` added to :attr:`notes` (how the set was made)."""
        return replace(self, notes=self.notes + (note,))

    def subset(self, mask_or_index) -> "Dataset":
        """The samples selected by a boolean mask or an index array."""
        idx = np.asarray(mask_or_index)
        return Dataset(self.X[idx], self.y[idx], self.t[idx], self.input_names, self.target_name,
                       self.flight[idx], self.sources, {k: v[idx] for k, v in self.extra.items()},
                       self.notes, self.screened)

    def to_frame(self):
        """A pandas DataFrame: inputs, then extras, then the target, then ``t`` and ``flight``."""
        import pandas as pd
        df = pd.DataFrame(self.X, columns=list(self.input_names))
        for k, v in self.extra.items():
            df[k] = v
        df[self.target_name] = self.y
        df["t"] = self.t
        df["flight"] = [self.sources[i] if i < len(self.sources) else str(i) for i in self.flight]
        return df
