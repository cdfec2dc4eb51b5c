"""``droneid fit``: SNGP symbolic regression on a plain CSV table."""
from __future__ import annotations

import json
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
    p.add_argument("--test", metavar="TEST.csv", help="test table with the same columns")
    p.add_argument("--target", required=True, metavar="COLUMN", help="column to model, e.g. vx_dot")
    p.add_argument("--inputs", metavar="a,b,c", help="comma-separated input columns")
    p.add_argument("--prior", action="append", default=[], metavar="EXPR",
                   help="prior feature over the inputs, e.g. '9.81*cos(yaw)*tan(pitch)/cos(roll)' "
                        "(repeatable; each counts toward --features)")
    p.add_argument("--constraints", metavar="FILE",
                   help="TOML constraint file (see priors/constraints.py); enables the constrained variant")
    p.add_argument("--constraint-samples", type=int, default=50, metavar="N",
                   help="samples per constraint for training and for test (default 50)")
    p.add_argument("--generations", type=int, default=60000, metavar="G")
    p.add_argument("--population", type=int, default=500, metavar="P")
    p.add_argument("--features", type=int, default=10, metavar="NF",
                   help="number of features nf, priors included (default 10)")
    p.add_argument("--depth", type=int, default=7, help="maximum tree depth (default 7)")
    p.add_argument("--functions", metavar="f,g,...",
                   help="function set (default add,sub,mul,square,cube,sin,cos)")
    p.add_argument("--gamma", type=float, default=0.05,
                   help="constraint error threshold in target units (default 0.05)")
    p.add_argument("--seed", type=int, default=None, metavar="S")
    p.add_argument("--save", metavar="MODEL.json", help="write the fitted model as JSON")
    p.add_argument("--json", action="store_true", help="print one JSON line with the results")
    p.set_defaults(func=run)


def read_table(path) -> "pandas.DataFrame":  # noqa: F821
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


def run(args) -> int:
    from ..sngp import SNGPRegressor
    from ..expressions import parse_expression
    from ._common import ProgressBar, print_json

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
    priors = [parse_expression(p, inputs, what=f"--prior {p!r}") for p in args.prior]
    functions = tuple(s.strip() for s in args.functions.split(",")) if args.functions else None
    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().generate_state(1)[0])
    cs_train = cs_test = None
    if args.constraints:
        cs_train, cs_test = load_constraint_samples(args.constraints, args.target, inputs,
                                                    args.constraint_samples, seed)
    quiet = getattr(args, "quiet", False) or args.json
    params = dict(generations=args.generations, population_size=args.population,
                  n_features=args.features, max_depth=args.depth, gamma=args.gamma, seed=seed,
                  progress=ProgressBar("fit", quiet=quiet))
    if functions:
        params["functions"] = functions
    model = SNGPRegressor(**params).fit(X, y, feature_names=inputs, priors=priors,
                                        constraints=cs_train)
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
    if cs_train is not None:
        line = f"constraint rmse train {model.constraint_rmse_train_:.4g}"
        if ec_test is not None:
            line += f", test {ec_test:.4g}"
        if not model.qualified_:
            line += f"  (no model reached gamma={args.gamma}: lowest-e_c model shown)"
        print(line)
    print(f"{model.generations_} generations in {model.wall_s_:.2f} s, seed {model.seed_}")
    return 0
