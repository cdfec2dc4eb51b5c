"""SNGP on a plain table: the pipeline behind ``droneid fit``, usable from Python.

``fit_table(train, FitConfig(target="vx_dot", priors=("tilt-drag",)), test=...)`` reads the
table(s) (a CSV path or a pandas DataFrame, one column per signal), takes every column but the
target, ``t`` and ``flight`` as an input unless ``inputs`` is given, drops rows with non-finite
values (counted), refuses data that cannot support a model (:func:`check_supports_model`), turns
each prior (an expression over the inputs, a built-in prior name or ``FILE.toml:NAME``) into prior
features, samples the constraint file if any, and fits :class:`droneid.sngp.SNGPRegressor`.
The :class:`FitResult` holds the fitted estimator and its errors; the CLI only prints it.
"""
from __future__ import annotations

import math
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from droneid.core.constraint_samples import ConstraintSamples
from droneid.errors import ConfigError, DataError, LogFormatError, MissingSignalError
from droneid.core.lazy import lazy_module
from droneid.sngp import SNGPRegressor

# sympy's side, loaded only when a fit has priors or constraints: without them the search starts
# before sympy is imported
_registry = lazy_module("priors.registry")
_constraints = lazy_module("priors.constraints")
_expressions = lazy_module("droneid.core.expressions")

if TYPE_CHECKING:
    import pandas as pd

#: the engine's own defaults (its signature), which fit keeps
_ENGINE = SNGPRegressor.default_params()

__all__ = ["FitConfig", "FitResult", "TableProblem", "prepare", "fit", "fit_table", "read_table",
           "check_supports_model", "prior_features", "NOT_INPUTS"]

#: columns never taken as inputs by default (time stamp, flight index)
NOT_INPUTS = ("t", "flight")
#: largest |value| a target may reach: squared errors of larger values overflow float64
_MAX_TARGET = 1e150
#: smallest non-zero max |value| of a target: squared errors of smaller ones underflow to 0
_MIN_TARGET = 1e-150
#: largest |value| of an input: evolved features cube and multiply inputs (1e100³ is 1e300)
_MAX_INPUT = 1e100
#: fewer rows than this many per coefficient: the training error is optimistic (a warning)
_ROWS_PER_COEF = 5


@dataclass(frozen=True)
class FitConfig:
    """What to fit and with which engine settings (the engine's own names, see
    :meth:`SNGPRegressor.param_names`).

    target : the column to model. inputs : input columns (None: every other column but
    :data:`NOT_INPUTS`). priors : prior specs, each an expression over the inputs, a built-in prior
    name (every term of it for ``target``) or ``FILE.toml:NAME``. constraints : a TOML constraint
    file (None: unconstrained); n_constraint_samples per constraint, for training and for test.
    functions : the function set (None: the engine's default). simplify_s : sympy's time budget
    (s) for simplifying the equation that is shown; 0 (fit's default, unlike the engine's): the
    terms as the search found them, rounded. What a budget achieves depends on the machine's
    load, and in a fresh process such as ``droneid fit`` the 0.5 s went into importing sympy's
    simplifier, so the equation came out unsimplified anyway, half a second later. n_jobs : cores
    the search threads may run on at once (the model does not depend on it).
    """
    target: str
    inputs: tuple[str, ...] | None = None
    priors: tuple[str, ...] = ()
    constraints: str | Path | None = None
    n_constraint_samples: int = 50
    generations: int = _ENGINE["generations"]
    population_size: int = _ENGINE["population_size"]
    n_features: int = _ENGINE["n_features"]
    max_depth: int = _ENGINE["max_depth"]
    gamma: float = _ENGINE["gamma"]
    seed: int = 0
    functions: tuple[str, ...] | None = None
    simplify_s: float = 0.0
    n_jobs: int = 1

    def engine_params(self) -> dict:
        """Keyword arguments of ``SNGPRegressor``: every estimator parameter this config names."""
        own = {f for f in self.__dataclass_fields__}
        params = {k: getattr(self, k) for k in SNGPRegressor.param_names() if k in own}
        if params.get("functions") is None:
            params.pop("functions", None)
        return params


@dataclass
class FitResult:
    """A fitted table model: the estimator, its inputs and its errors (m/s² for a v̇ target; in
    general the target's unit). ``rmse_test`` / ``constraint_rmse_*`` are None when not measured."""
    estimator: SNGPRegressor
    target: str
    inputs: tuple[str, ...]
    rmse_train: float
    rmse_test: float | None = None
    constraint_rmse_train: float | None = None
    constraint_rmse_test: float | None = None
    dropped_rows: int = 0
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        """The figures ``droneid fit --json`` prints (non-finite numbers as None)."""
        def num(v):
            return None if v is None or not math.isfinite(v) else float(v)
        m = self.estimator
        return {"equation": m.equation_, "rmse_train": num(self.rmse_train),
                "rmse_test": num(self.rmse_test),
                "constraint_rmse_train": num(self.constraint_rmse_train),
                "constraint_rmse_test": num(self.constraint_rmse_test), "wall_s": round(m.wall_s_, 3),
                "generations": m.generations_, "seed": m.seed_}

    def model_dict(self) -> dict:
        """The fitted model as JSON data (``--save``), with its target."""
        return {**self.estimator.to_dict(), "target": self.target}


def read_table(path) -> "pd.DataFrame":
    """A CSV table with a header row; LogFormatError naming the file when it is not one."""
    import pandas as pd
    path = Path(path)
    if not path.is_file():
        raise LogFormatError(path, "no such file")
    try:
        df = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise LogFormatError(path, f"not a readable CSV table: {str(exc).splitlines()[0]}") from None
    if df.empty or df.shape[1] < 2:
        raise LogFormatError(path, "the table needs a header and at least two columns with rows")
    return df


#: a decimal number as a plain CSV table writes it (no spaces, no NaN/inf words, no thousands)
_PLAIN_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
#: an integer token longer than this may leave int64 in pandas (uint64, object): not plain
_MAX_INT_DIGITS = 18


def read_plain_table(path) -> dict[str, np.ndarray | None] | None:
    """A plain numeric CSV table read without pandas (whose import is a fifth of a ``droneid fit``
    start-up): ``{column: float64 array}``, the columns in file order; a ``flight`` column of
    names is kept as None. None when the file is anything else: not UTF-8, a byte-order mark,
    quotes, blank or ragged rows, empty or repeated column names, a field that is not a plain
    decimal number (spaces, NaN, inf, missing values) or an integer too long for int64; pandas
    then reads it (:func:`read_table`).

    The values are those pandas gives: on such fields pandas' parser and Python's ``float`` both
    round correctly (tests/unit/test_fit_plain_table.py checks them side by side), and an integer
    column that pandas reads as int64 converts to the same float64."""
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    if not text or text[0] == "\ufeff" or '"' in text:
        return None
    lines = text.split("\n")
    while lines and lines[-1] in ("", "\r"):
        lines.pop()
    lines = [ln[:-1] if ln.endswith("\r") else ln for ln in lines]
    if len(lines) < 2 or any(not ln or "\r" in ln for ln in lines):
        return None
    names = lines[0].split(",")
    if len(names) < 2 or len(set(names)) != len(names) or not all(names):
        return None
    rows = [ln.split(",") for ln in lines[1:]]
    if any(len(r) != len(names) for r in rows):
        return None
    table: dict[str, np.ndarray | None] = {}
    for j, name in enumerate(names):
        tokens = [r[j] for r in rows]
        if not all(_PLAIN_NUMBER.fullmatch(t) for t in tokens):
            if name != "flight":
                return None
            table[name] = None        # log names: never an input by default
            continue
        integers = [t.lstrip("+-").isdigit() for t in tokens]
        if any(i and len(t.lstrip("+-")) > _MAX_INT_DIGITS for i, t in zip(integers, tokens)):
            return None
        if all(integers):   # pandas: an int64 column, then float64 ("-0" is 0.0, not -0.0)
            table[name] = np.array([float(int(t)) for t in tokens], dtype=np.float64)
        else:
            table[name] = np.array([float(t) for t in tokens], dtype=np.float64)
    return table


def _columns(table, names, where) -> np.ndarray:
    """The ``names`` columns of ``table`` (a DataFrame or a :func:`read_plain_table` dict) as
    float64 columns of one array."""
    out = []
    for n in names:
        if n not in table:
            raise MissingSignalError(n, [str(c) for c in table], where=str(where))
        try:
            out.append(np.asarray(table[n], dtype=np.float64) if isinstance(table, dict)
                       else table[n].to_numpy(dtype=np.float64))
        except (ValueError, TypeError):
            raise DataError(f"{where}: column '{n}' is not numeric") from None
    return np.column_stack(out)


def _finite_rows(X, y):
    ok = np.isfinite(X).all(axis=1) & np.isfinite(y)
    return X[ok], y[ok], int((~ok).sum())


def check_supports_model(X: np.ndarray, y: np.ndarray, inputs, target: str, n_coef: int,
                         where) -> str | None:
    """Raise :class:`DataError` when the table cannot support a model of ``n_coef`` coefficients
    (intercept + features): too few rows to leave a residual, or values whose squared errors
    leave float64 (rescale the column). Returns a warning when the rows are few per coefficient."""
    rows = y.size
    if rows <= n_coef:
        raise DataError(f"{where}: {rows} rows with finite values cannot support a model of up to "
                        f"{n_coef} coefficients (intercept + --features {n_coef - 1}): any such model "
                        f"fits them exactly; give more than {n_coef} rows or lower --features")
    top = float(np.max(np.abs(y)))
    if top > _MAX_TARGET:
        raise DataError(f"{where}: target '{target}' reaches {top:.3g}; squared errors overflow "
                        f"float64 beyond {_MAX_TARGET:.0e}: rescale it (other units)")
    if 0 < top < _MIN_TARGET:
        raise DataError(f"{where}: target '{target}' is at most {top:.3g} in magnitude; squared errors "
                        f"underflow to 0 below {_MIN_TARGET:.0e}: rescale it (other units)")
    big = np.max(np.abs(X), axis=0)
    if big.size and big.max() > _MAX_INPUT:
        j = int(np.argmax(big))
        raise DataError(f"{where}: input '{inputs[j]}' reaches {big[j]:.3g}; products and cubes of "
                        f"inputs beyond {_MAX_INPUT:.0e} overflow float64: rescale it (other units)")
    if rows < _ROWS_PER_COEF * n_coef:
        return (f"only {rows} rows for up to {n_coef} coefficients: the training error is "
                f"optimistic; judge the model on --test data or lower --features")
    return None


def prior_features(spec: str, inputs: Sequence[str], target: str) -> list:
    """The prior feature(s) one prior spec gives: a built-in prior name or ``FILE.toml:NAME``
    (every term of that model for ``target``), else an expression over ``inputs``."""
    # sympy only with priors: without them the search starts before sympy is imported
    if _registry.is_prior_spec(spec):
        exprs = [f.expr for f in _registry.resolve_prior(spec).features(target)]
        for e in exprs:
            unknown = sorted(s.name for s in e.free_symbols if s.name not in inputs)
            if unknown:
                raise MissingSignalError(unknown[0], list(inputs), where=f"the inputs (--prior {spec})")
        return exprs
    return [_expressions.parse_expression(spec, list(inputs), what=f"--prior {spec!r}")]


def _table(data, where, needed) -> tuple:
    """``(table, where)``: a DataFrame as given; a CSV path as a plain table when it is one and
    the columns ``needed(columns)`` names are all numeric in it (:func:`read_plain_table`),
    else as read by pandas (:func:`read_table`, whose errors name the file)."""
    pd = sys.modules.get("pandas")      # no DataFrame exists before pandas is imported
    if pd is not None and isinstance(data, pd.DataFrame):
        return data, where
    plain = read_plain_table(data)
    if plain is not None and all(plain.get(n, 0) is not None for n in needed(plain)):
        return plain, str(data)
    return read_table(data), str(data)


def _inputs(columns, config: FitConfig) -> tuple[str, ...]:
    """The input columns: ``config.inputs``, else every column but the target and NOT_INPUTS."""
    if config.inputs:
        return tuple(config.inputs)
    return tuple(str(c) for c in columns if c != config.target and c not in NOT_INPUTS)


@dataclass(frozen=True)
class TableProblem:
    """A checked table problem, ready for the engine: training arrays, prior features,
    constraint samples and the test arrays (None without a test table)."""
    inputs: tuple[str, ...]
    X: np.ndarray
    y: np.ndarray
    priors: tuple
    constraints_train: ConstraintSamples | None
    constraints_test: ConstraintSamples | None
    X_test: np.ndarray | None
    y_test: np.ndarray | None
    dropped_rows: int
    warnings: tuple[str, ...]
    source: str = "the training table"


def prepare(train, config: FitConfig, test=None) -> TableProblem:
    """Read and check the tables (CSV paths or DataFrames) before any search: bad input fails
    here, in seconds, with one line naming the file and the problem."""
    SNGPRegressor.validate_params(config.engine_params(), owner="FitConfig")
    df, where = _table(train, "the training table",
                       lambda columns: (*_inputs(columns, config), config.target))
    inputs = _inputs(df, config)
    if not inputs:
        raise ConfigError("no input columns (give --inputs)")
    if config.target in inputs:
        raise ConfigError(f"the target '{config.target}' cannot also be an input")
    X = _columns(df, inputs, where)
    y = _columns(df, [config.target], where)[:, 0]
    X, y, dropped = _finite_rows(X, y)
    if y.size < 3:
        raise DataError(f"{where}: fewer than 3 rows with finite values")
    warning = check_supports_model(X, y, inputs, config.target, config.n_features + 1, where)
    priors = tuple(e for p in config.priors for e in prior_features(p, inputs, config.target))
    cs_train = cs_test = None
    if config.constraints:
        cset = _constraints.load_constraints(config.constraints, target=config.target)
        cs_train, cs_test = cset.train_test(inputs, n_per_constraint=config.n_constraint_samples,
                                            seed=config.seed)
    Xt = yt = None
    if test is not None:
        dft, twhere = _table(test, "the test table", lambda columns: (*inputs, config.target))
        Xt, yt, _ = _finite_rows(_columns(dft, inputs, twhere), _columns(dft, [config.target], twhere)[:, 0])
    return TableProblem(inputs, X, y, priors, cs_train, cs_test, Xt, yt, dropped,
                        (warning,) if warning else (), where)


def fit(problem: TableProblem, config: FitConfig, progress: Callable | None = None) -> FitResult:
    """Run the engine on a prepared problem; ``progress(done, total, message)`` as the engine's."""
    estimator = SNGPRegressor(progress=progress, **config.engine_params())
    estimator.fit(problem.X, problem.y, feature_names=list(problem.inputs), priors=list(problem.priors),
                  constraints=problem.constraints_train)
    if not math.isfinite(estimator.rmse_train_):
        raise DataError(f"{problem.source}: the training error of the fitted model is not finite; "
                        "the data cannot support a model (check the scale of every column)")
    rmse_test = None
    if problem.y_test is not None and problem.y_test.size:
        rmse_test = estimator.rmse(problem.X_test, problem.y_test)
    return FitResult(
        estimator, config.target, problem.inputs, float(estimator.rmse_train_), rmse_test,
        float(estimator.constraint_rmse_train_) if problem.constraints_train is not None else None,
        _constraint_rmse(estimator, problem.constraints_test), problem.dropped_rows,
        list(problem.warnings))


def fit_table(train, config: FitConfig, test=None, progress: Callable | None = None) -> FitResult:
    """Fit ``config.target`` on the ``train`` table (CSV path or DataFrame); ``test`` (same
    columns) is only reported: :func:`prepare` then :func:`fit`."""
    return fit(prepare(train, config, test), config, progress)


def _constraint_rmse(estimator: SNGPRegressor, samples: ConstraintSamples | None) -> float | None:
    return estimator.constraint_rmse(samples) if samples is not None else None
