"""``droneid fit``: SNGP symbolic regression on a plain CSV table."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import ConfigError, DataError, LogFormatError, MissingSignalError

NOT_INPUTS = ("t", "flight")


def register(sub) -> None:
    p = sub.add_parser(
        "fit", help="fit an analytic model to a CSV table with SNGP (priors, constraints)",
        description="SNGP symbolic regression: TARGET = b0 + sum b_i prior_i + sum b_j feature_j. "
                    "Without --inputs every column other than the target, t and flight is an input.")
    p.add_argument("train", metavar="TRAIN.csv", help="training table (one column per signal)")
    p.add_argument("--test", metavar="TEST.csv",
                   help="test table with the same columns; its RMSE is reported (default: none)")
    p.add_argument("--target", required=True, metavar="COLUMN", help="column to model, e.g. vx_dot")
    p.add_argument("--inputs", metavar="a,b,c",
                   help="comma-separated input columns (default: every column but the target, t and flight)")
    p.add_argument("--prior", action="append", default=[], metavar="EXPR|FILE.toml:NAME",
                   help="prior feature over the inputs, e.g. '9.81*cos(yaw)*tan(pitch)/cos(roll)', or "
                        "every term of a prior model for --target: a built-in name (tilt-drag) or "
                        "FILE.toml:NAME (repeatable; each feature counts toward --features; default: none)")
    p.add_argument("--constraints", metavar="FILE",
                   help="TOML constraint file (see priors/constraints.py); enables the constrained variant "
                        "(default: none, unconstrained)")
    p.add_argument("--constraint-samples", type=int, default=50, metavar="N",
                   help="samples per constraint for training and for test (default 50)")
    p.add_argument("--generations", type=int, default=60000, metavar="G",
                   help="SNGP generations (default 60000, the paper's; try 3000 for a quick look)")
    p.add_argument("--population", type=int, default=500, metavar="P",
                   help="SNGP population size (default 500, the paper's)")
    p.add_argument("--features", type=int, default=10, metavar="NF",
                   help="number of features nf, priors included (default 10)")
    p.add_argument("--depth", type=int, default=7, help="maximum tree depth (default 7)")
    p.add_argument("--functions", metavar="f,g,...",
                   help="function set (default add,sub,mul,square,cube,sin,cos)")
    p.add_argument("--gamma", type=float, default=0.05,
                   help="constraint error threshold in target units (default 0.05)")
    p.add_argument("--seed", type=int, default=0, metavar="S",
                   help="random seed; the same seed and data give the same model (default 0, as identify)")
    p.add_argument("--save", metavar="MODEL.json", help="write the fitted model as JSON (default: not saved)")
    p.add_argument("--json", action="store_true", help="print one JSON line with the results")
    p.set_defaults(func=run)


def read_table(path):
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


def _columns(df, names, path) -> np.ndarray:
    out = []
    for n in names:
        if n not in df.columns:
            raise MissingSignalError(n, [str(c) for c in df.columns], where=str(path))
        col = df[n]
        try:
            v = col.to_numpy(dtype=np.float64)
        except (ValueError, TypeError):
            raise DataError(f"{path}: column '{n}' is not numeric") from None
        out.append(v)
    return np.column_stack(out)


def _finite_rows(X, y):
    ok = np.isfinite(X).all(axis=1) & np.isfinite(y)
    return X[ok], y[ok], int((~ok).sum())


def load_constraint_samples(path, target, inputs, n, seed):
    """(train, test) ConstraintSamples from a TOML constraint file (priors.constraints)."""
    try:
        from priors.constraints import load_constraints
    except ImportError:  # pragma: no cover - the module ships with droneid
        raise ConfigError("--constraints needs priors.constraints, which is not installed") from None
    cset = load_constraints(path, target=target)
    if hasattr(cset, "train_test"):
        return cset.train_test(inputs, n_per_constraint=n, seed=seed)
    s_train, s_test = np.random.SeedSequence(seed).spawn(2)
    return cset.sample(inputs, n_per_constraint=n, seed=s_train), \
        cset.sample(inputs, n_per_constraint=n, seed=s_test)


#: largest |value| a target may reach: squared errors of larger values overflow float64
_MAX_TARGET = 1e150
#: smallest non-zero max |value| of a target: squared errors of smaller ones underflow to 0
_MIN_TARGET = 1e-150
#: largest |value| of an input: evolved features cube and multiply inputs (1e100³ is 1e300)
_MAX_INPUT = 1e100
#: fewer rows than this many per coefficient: the training error is optimistic (a warning)
_ROWS_PER_COEF = 5


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


def prior_features(spec: str, inputs, target: str) -> list:
    """The prior feature(s) one ``--prior`` gives: a built-in prior name or ``FILE.toml:NAME``
    (every term of that model for ``target``), else an expression over ``inputs``."""
    from priors.models import PRIORS, resolve_prior

    from ..expressions import parse_expression
    if spec in PRIORS or (":" in spec and spec.split(":", 1)[0].endswith(".toml")):
        exprs = [f.expr for f in resolve_prior(spec).features(target)]
        for e in exprs:
            unknown = sorted(s.name for s in e.free_symbols if s.name not in inputs)
            if unknown:
                raise MissingSignalError(unknown[0], inputs, where=f"the inputs (--prior {spec})")
        return exprs
    return [parse_expression(spec, inputs, what=f"--prior {spec!r}")]


def run(args) -> int:
    import sys

    from ..runner import startup_message
    from ..sngp import SNGPRegressor
    from ._common import ProgressBar, print_json

    if args.save and Path(args.save).is_dir():
        raise ConfigError(f"--save {args.save}: is a folder; give a file name such as "
                          f"{Path(args.save) / 'model.json'}")
    df = read_table(args.train)
    if args.inputs:
        inputs = [s.strip() for s in args.inputs.split(",") if s.strip()]
    else:
        inputs = [str(c) for c in df.columns if c != args.target and c not in NOT_INPUTS]
    if not inputs:
        raise ConfigError("no input columns (give --inputs)")
    if args.target in inputs:
        raise ConfigError(f"the target '{args.target}' cannot also be an input")
    X = _columns(df, inputs, args.train)
    y = _columns(df, [args.target], args.train)[:, 0]
    X, y, dropped = _finite_rows(X, y)
    if y.size < 3:
        raise DataError(f"{args.train}: fewer than 3 rows with finite values")
    warning = check_supports_model(X, y, inputs, args.target, args.features + 1, args.train)
    priors = [e for p in args.prior for e in prior_features(p, inputs, args.target)]
    functions = tuple(s.strip() for s in args.functions.split(",")) if args.functions else None
    seed = args.seed
    cs_train = cs_test = None
    if args.constraints:
        cs_train, cs_test = load_constraint_samples(args.constraints, args.target, inputs,
                                                    args.constraint_samples, seed)
    quiet = getattr(args, "quiet", False) or args.json
    if warning:
        print(f"droneid fit: warning: {warning}", file=sys.stderr)
    bar = ProgressBar("fit", quiet=quiet)
    params = dict(generations=args.generations, population_size=args.population,
                  n_features=args.features, max_depth=args.depth, gamma=args.gamma, seed=seed,
                  progress=bar)
    if functions:
        params["functions"] = functions
    estimator = SNGPRegressor(**params)
    bar(0, args.generations, startup_message())
    model = estimator.fit(X, y, feature_names=inputs, priors=priors, constraints=cs_train)
    if not math.isfinite(model.rmse_train_):
        raise DataError(f"{args.train}: the training error of the fitted model is not finite; "
                        "the data cannot support a model (check the scale of every column)")
    rmse_test = None
    if args.test:
        dft = read_table(args.test)
        Xt = _columns(dft, inputs, args.test)
        yt = _columns(dft, [args.target], args.test)[:, 0]
        Xt, yt, _ = _finite_rows(Xt, yt)
        rmse_test = model.rmse(Xt, yt) if yt.size else None
    ec_test = model.constraint_rmse(cs_test) if cs_test is not None else None

    def num(v):
        return None if v is None or not math.isfinite(v) else float(v)

    if args.save:
        from ..io_util import atomic_write_json
        d = model.to_dict()
        d["target"] = args.target
        atomic_write_json(args.save, d)
    out = {"equation": model.equation_, "rmse_train": num(model.rmse_train_),
           "rmse_test": num(rmse_test),
           "constraint_rmse_train": num(model.constraint_rmse_train_) if cs_train is not None else None,
           "constraint_rmse_test": num(ec_test), "wall_s": round(model.wall_s_, 3),
           "generations": model.generations_, "seed": model.seed_}
    if args.json:
        print_json(out)
        return 0
    print(f"{args.target} = {model.equation_}")
    for sym, expr in model.model_.priors.items():
        beta = model.prior_coef_[model.model_.prior_labels[sym]]
        print(f"  {sym} = {expr}  (coefficient {beta:.4g})")
    print(f"rmse train {model.rmse_train_:.4g}" + (f", test {rmse_test:.4g}" if rmse_test is not None else "")
          + (f" ({dropped} non-finite training rows dropped)" if dropped else ""))
    if rmse_test is not None and not math.isfinite(rmse_test):
        print("droneid fit: warning: the test error is not finite: the model overflows on the test "
              "data (inputs outside the training range?)", file=sys.stderr)
    if cs_train is not None:
        line = f"constraint rmse train {model.constraint_rmse_train_:.4g}"
        if ec_test is not None:
            line += f", test {ec_test:.4g}"
        if not model.qualified_:
            line += f"  (no model reached gamma={args.gamma}: lowest-e_c model shown)"
        print(line)
    print(f"{model.generations_} generations in {model.wall_s_:.2f} s, seed {model.seed_}")
    return 0
