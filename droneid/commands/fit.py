"""``droneid fit``: SNGP symbolic regression on a plain CSV table (the pipeline is
:func:`droneid.engine.fit.fit_table`; this module parses the options and prints the result)."""
from __future__ import annotations

import contextlib
import gc
import importlib
import math
import sys
import threading
from pathlib import Path

from droneid.errors import ConfigError
from droneid.core.io_util import atomic_write_json
from droneid.engine.runner import default_jobs, startup_message
from droneid.core.lazy import lazy_module
from droneid.commands._common import ProgressBar, print_json

# the engine: loaded once the command runs (then sympy's import starts in the background)
_fit = lazy_module("droneid.engine.fit")
_engine = lazy_module("droneid.sngp")


def register(sub) -> None:
    p = sub.add_parser(
        "fit",
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
    p.add_argument("--simplify", type=float, default=0.0, metavar="S",
                   help="let sympy simplify the shown equation for up to S seconds (default 0: the "
                        "terms as found, rounded; a budget's result depends on the machine's load)")
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="cores the search may use (default: all; the model does not depend on it)")
    p.add_argument("--save", metavar="MODEL.json", help="write the fitted model as JSON (default: not saved)")
    p.add_argument("--json", action="store_true", help="print one JSON line with the results")
    p.set_defaults(func=run)


def run(args) -> int:
    with _collector_paused():   # the imports and the search; the equation is built after
        res = _fitted(args)
    if args.save:
        atomic_write_json(args.save, res.model_dict())
    if args.json:
        print_json(res.to_dict())
        return 0
    model = res.estimator
    print(f"{args.target} = {model.equation_}")
    for sym, expr in model.model_.priors.items():
        beta = model.prior_coef_[model.model_.prior_labels[sym]]
        print(f"  {sym} = {expr}  (coefficient {beta:.4g})")
    print(f"rmse train {res.rmse_train:.4g}" + (f", test {res.rmse_test:.4g}" if res.rmse_test is not None else "")
          + (f" ({res.dropped_rows} non-finite training rows dropped)" if res.dropped_rows else ""))
    if res.rmse_test is not None and not math.isfinite(res.rmse_test):
        print("droneid fit: warning: the test error is not finite: the model overflows on the test "
              "data (inputs outside the training range?)", file=sys.stderr)
    if res.constraint_rmse_train is not None:
        line = f"constraint rmse train {res.constraint_rmse_train:.4g}"
        if res.constraint_rmse_test is not None:
            line += f", test {res.constraint_rmse_test:.4g}"
        if not model.qualified_:
            line += f"  (no model reached gamma={args.gamma}: lowest-e_c model shown)"
        print(line)
    print(f"{model.generations_} generations in {model.wall_s_:.2f} s, seed {model.seed_}")
    return 0


def _fitted(args):
    """Check the options, read the table(s) and fit: the :class:`~droneid.engine.fit.FitResult`."""
    if args.save and Path(args.save).is_dir():
        raise ConfigError(f"--save {args.save}: is a folder; give a file name such as "
                          f"{Path(args.save) / 'model.json'}")
    inputs = tuple(s.strip() for s in args.inputs.split(",") if s.strip()) if args.inputs else None
    if args.inputs and not inputs:
        raise ConfigError("no input columns (give --inputs)")
    functions = tuple(s.strip() for s in args.functions.split(",")) if args.functions else None
    config = _fit.FitConfig(target=args.target, inputs=inputs, priors=tuple(args.prior),
                       constraints=args.constraints, n_constraint_samples=args.constraint_samples,
                       generations=args.generations, population_size=args.population,
                       n_features=args.features, max_depth=args.depth, gamma=args.gamma,
                       seed=args.seed, functions=functions, simplify_s=args.simplify,
                       n_jobs=args.jobs if args.jobs is not None else default_jobs())
    _import_sympy_meanwhile()    # the engine (numba) is imported now: see there
    problem = _fit.prepare(args.train, config, test=args.test)
    for w in problem.warnings:
        print(f"droneid fit: warning: {w}", file=sys.stderr)
    bar = ProgressBar("fit", quiet=getattr(args, "quiet", False) or args.json)
    bar(0, args.generations, startup_message())
    _engine.kernels.set_up_target(skip_blas_probe=True)   # this process runs only the SNGP kernels
    return _fit.fit(problem, config, progress=bar)


@contextlib.contextmanager
def _collector_paused():
    """Python's cyclic garbage collector off while the command imports and searches (restored
    after, before the equation is built: ``--simplify`` may run sympy for long): the imports of
    numpy, numba and sympy create ~170,000 objects, and the collections they trigger scan them
    again and again (~0.1 s CPU of a ``droneid fit`` start-up); the search makes few Python
    objects. Memory only: the results are the same. On the way out every object is moved to the oldest generation (freeze, then
    unfreeze), where the young collections that resume do not scan them again: else the first
    allocation after ``gc.enable`` would scan them all at once."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.unfreeze()
        if enabled:
            gc.enable()


def _import_sympy_meanwhile() -> None:
    """Start importing sympy (the equation is built with it) in a background thread once the
    engine is imported and before numba's set-up: that set-up, the loading of the cached kernels
    (largely in LLVM) and the search release the GIL, so the import fills time the other core
    would leave idle instead of waiting until the search ends. Not earlier: importing numba and
    the engine holds the GIL, and two imports at once only take turns. Imports only: the model
    and its printed equation are the same either way."""
    if "sympy" not in sys.modules:
        threading.Thread(target=_import_quietly, name="droneid-import-sympy", daemon=True).start()


#: what building the equation and the test error import besides droneid.sngp.model (sympy and
#: the expression tools), each on first use: sympy's sums sympy.tensor.tensor (and with it
#: sympy.combinatorics), its code printer sympy.codegen.ast, sets sympy.sets.setexpr, and
#: sympy.lambdify's numpy namespace is ``from numpy import *`` and ``from numpy.linalg import *``,
#: which loads numpy's lazy submodules (f2py, testing, fft, ...): ~0.1 s of CPU that came after
#: the search, on the path to the printed equation
_SYMBOLIC_SIDE = ("droneid.sngp.model", "sympy.tensor.tensor", "sympy.codegen.ast",
                  "sympy.sets.setexpr")
_STAR_IMPORTED = ("numpy", "numpy.linalg")


def _import_quietly() -> None:
    """Import the symbolic side (:data:`_SYMBOLIC_SIDE`, :data:`_STAR_IMPORTED`'s names). Only
    imports, each under the import system's own lock: a thread that needs a module meanwhile
    waits for it, fully executed, and none of sympy's own state is touched. A module that fails
    (another sympy or numpy) is skipped: whoever needs it imports it and reports the error."""
    for name in _SYMBOLIC_SIDE + _STAR_IMPORTED:
        try:
            module = importlib.import_module(name)
            if name in _STAR_IMPORTED:
                for attr in getattr(module, "__all__", ()):
                    getattr(module, attr, None)
        except Exception:   # noqa: BLE001 - see above
            continue
