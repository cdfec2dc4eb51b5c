"""SNGPRegressor: the estimator-style front of the engine (validation, search, model building).

``__init__`` only stores keyword parameters (unknown names are rejected with a suggestion);
``fit`` validates (:meth:`SNGPRegressor.validate_params`, the one home of the engine's
parameter rules), runs the compiled search (:mod:`droneid.sngp.search`), prunes dead features
and fills the ``*_`` attributes; the simplified equation and its other forms are built on first
use (:mod:`droneid.sngp.render`, which also holds the symbolic side: sympy is imported only
there, in the background while a search without priors runs).
"""
from __future__ import annotations

import inspect
import logging
import math
import re
import time
from collections.abc import Mapping, Sequence

import numpy as np

from droneid.core.constraint_samples import ConstraintSamples, constraint_rmse
from droneid.errors import (ConfigError, DataError, MissingSignalError, NotFittedError, check_choice,
                      did_you_mean)
from droneid.core.lazy import lazy_module
from droneid.core.numerics import lstsq as _lstsq
from droneid.core.numerics import rmse
from droneid.dataset.validation import block_ids
from droneid.sngp import kernels as K
from droneid.sngp import population as popmod
from droneid.sngp.kernels import kernels_ready
from droneid.sngp.operators import DEFAULT_FUNCTIONS
from droneid.sngp.operators import names as operator_names
from droneid.sngp.population import Population, Problem
from droneid.sngp.render import ArchiveEntry, import_symbolic_side, is_sympy, links_equation, node_exprs, render
from droneid.sngp.search import run_search

# sympy's side, loaded when a fit has priors or writes its equation: without priors the search
# runs before sympy is imported
_expressions = lazy_module("droneid.core.expressions")
_model = lazy_module("droneid.sngp.model")
from droneid.sngp.selection import best_index

log = logging.getLogger(__name__)

__all__ = ["SNGPRegressor"]

_RESERVED = {"pi", "e", "E", "I", "N", "S", "O", "Q", "oo", "nan", "zoo"}
PRUNE_RTOL = 1e-6
#: prune="validation": an evolved feature stays only if dropping it raises the held-out RMSE by
#: more than this fraction (with ~90 held-out samples, a term fitting noise often wins < 1 %)
VALIDATION_MIN_GAIN = 0.01


class SNGPRegressor:
    """Single Node Genetic Programming with prior features and formal constraints.

    Parameters (keyword only): ``functions`` (names from the operator table), ``population_size``
    (nodes), ``generations``, ``n_features`` (nf, prior features included), ``max_depth``,
    ``gamma`` (e_c threshold of the constrained variant, target units), ``n_epochs``,
    ``n_threads`` (search threads per epoch, each from the epoch's best population),
    ``seed`` (None: drawn),
    ``progress`` (callable(done, total, message)), ``identity_steps`` (local steps relinking
    feature slots at the end of each thread), ``simplify_s`` (sympy time budget; 0 disables),
    ``prune`` ("exact": drop only features whose removal changes the training RMSE by < 1e-6
    relative, as the spec says; "validation": the search sees only ``1 - validation_fraction``
    of the training rows (contiguous blocks), evolved features are then dropped by backward
    elimination while the error on the held-out blocks rises by less than 1 %, and the kept ones are
    refit on all training rows: terms that only fit the noise of the search rows go),
    ``early_stop_window`` (generations; the search stops when the error of its best model has
    not improved by the relative ``early_stop_margin`` over this many generations; the error is
    the one on the held-out rows with ``prune="validation"``, else the training error (the
    constrained variant: e_d once a model qualifies, e_c before); None or 0: always run all
    ``generations``, the paper's protocol), ``n_jobs`` (cores the threads of an epoch may run
    on at once: the unconstrained variant runs up to ``n_threads`` of them side by side, with
    the same result as one after the other; it changes how fast, never what, so it is not
    recorded in :meth:`to_dict`). ``generations_`` reports the generations run and
    ``stopped_early_`` whether the window ended the search.
    """

    def __init__(self, *, functions=DEFAULT_FUNCTIONS, population_size=500, generations=60000,
                 n_features=10, max_depth=7, gamma=0.05, n_epochs=30, n_threads=2, seed=None,
                 progress=None, identity_steps=100, simplify_s=0.5, prune="exact",
                 validation_fraction=0.25, early_stop_window=10000, early_stop_margin=0.001,
                 n_jobs=1, **unknown):
        if unknown:
            name = next(iter(unknown))
            raise ConfigError(f"SNGPRegressor got an unknown parameter '{name}'"
                              f"{did_you_mean(name, _PARAMS)}; valid: {', '.join(_PARAMS)}")
        self.functions = functions
        self.population_size = population_size
        self.generations = generations
        self.n_features = n_features
        self.max_depth = max_depth
        self.gamma = gamma
        self.n_epochs = n_epochs
        self.n_threads = n_threads
        self.seed = seed
        self.progress = progress
        self.identity_steps = identity_steps
        self.simplify_s = simplify_s
        self.prune = prune
        self.validation_fraction = validation_fraction
        self.early_stop_window = early_stop_window
        self.early_stop_margin = early_stop_margin
        self.n_jobs = n_jobs

    # -- sklearn-style parameter access -------------------------------------------------------
    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        """The estimator's parameter names, read from its signature: the one list that
        configs (``IdentifyConfig``, ``DiagnoseConfig``) take their engine names from."""
        return tuple(_PARAMS)

    @classmethod
    def default_params(cls) -> dict:
        """The estimator's parameter defaults by name, read from its signature (configs that
        do not choose otherwise take theirs from here)."""
        return dict(_PARAMS)

    def get_params(self, deep: bool = True) -> dict:
        return {k: getattr(self, k) for k in _PARAMS}

    def set_params(self, **params) -> "SNGPRegressor":
        for k, v in params.items():
            if k not in _PARAMS:
                raise ConfigError(f"SNGPRegressor has no parameter '{k}'{did_you_mean(k, _PARAMS)}")
            setattr(self, k, v)
        return self

    def __repr__(self) -> str:
        changed = {k: v for k, v in self.get_params().items() if v is not _PARAMS[k] and v != _PARAMS[k]}
        return f"SNGPRegressor({', '.join(f'{k}={v!r}' for k, v in changed.items())})"

    # -- validation ----------------------------------------------------------------------------
    @classmethod
    def validate_params(cls, params: Mapping, owner: str = "SNGPRegressor") -> dict:
        """Check engine parameters by name: the one home of their rules (configs that pass them
        on call it too). ``params``: any of :meth:`param_names` (only those given are checked);
        returns them as a new dict. Raises :class:`~droneid.errors.ConfigError`: an unknown
        name (with the nearest valid one), or "The 'x' parameter of ``owner`` must be ... Got ...
        instead."."""
        params = dict(params)
        for name in params:
            if name not in _PARAMS:
                raise ConfigError(f"{owner} has no engine parameter '{name}'"
                                  f"{did_you_mean(name, _PARAMS)}; valid: {', '.join(_PARAMS)}")
        for name in _PARAMS:     # signature order: the first bad one is reported
            if name in params:
                _check_param(name, params[name], owner)
        return params

    def _validate_params(self) -> None:
        self.validate_params(self.get_params())

    # -- fit -----------------------------------------------------------------------------------
    def fit(self, X, y, *, feature_names=None, priors=(), prior_names=None, constraints=None):
        t_start = time.perf_counter()
        self._validate_params()
        X = np.asarray(X, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64).ravel()
        if X.ndim != 2:
            raise DataError(f"X must be a 2-D array (samples x inputs), got shape {X.shape}")
        if X.shape[0] != y.size:
            raise DataError(f"X has {X.shape[0]} rows but y has {y.size} values")
        if y.size < 3:
            raise DataError(f"SNGP needs at least 3 training samples, got {y.size}")
        if not np.isfinite(X).all() or not np.isfinite(y).all():
            raise DataError("X and y must be finite (drop or interpolate NaN/inf samples first)")
        names = self._feature_names(feature_names, X.shape[1])
        prior_exprs, prior_syms, prior_labels = self._priors(priors, prior_names, names)
        n_prior = len(prior_exprs)
        if n_prior > self.n_features:
            raise ConfigError(f"{n_prior} prior features exceed n_features={self.n_features} "
                              "(prior features count toward nf)")
        cs = self._constraints(constraints, names)
        constrained = cs is not None and len(cs) > 0
        X_all, y_all = X, y
        val = _validation_rows(y.size, float(self.validation_fraction)) \
            if self.prune == "validation" else None
        if val is not None:
            X, y = X_all[~val], y_all[~val]

        seed = int(self.seed) if self.seed is not None else \
            int(np.random.SeedSequence().generate_state(1)[0])
        rng = np.random.default_rng(np.random.SeedSequence(seed))

        # terminal rows: inputs then priors, over training columns then constraint columns
        Xall = X if not constrained else np.vstack([X, cs.X])
        terminals = popmod.terminal_rows(Xall, y.size, names, prior_syms, prior_exprs, prior_labels)
        yc = y - y.mean()
        if constrained:
            ckind = np.asarray(cs.kind, dtype=np.int64)
            cbound = np.asarray(cs.bound, dtype=np.float64)
        else:
            ckind, cbound = np.zeros(0, dtype=np.int64), np.zeros(0)
        problem = Problem(y=y.copy(), yc=yc, syy=float(yc @ yc), ckind=ckind, cbound=cbound,
                          terminals=terminals)
        K.use_cached_code()    # the first kernel call follows: read cached code lightly
        try:
            template = popmod.build_population(
                tuple(self.functions), int(self.population_size), len(names), n_prior,
                int(self.n_features) - n_prior, int(self.max_depth), y.size, Xall.shape[0],
                constrained, rng)
        except ValueError as exc:
            raise ConfigError(f"The 'population_size' parameter of SNGPRegressor is too small: "
                              f"{exc}") from None
        if self.progress is not None and not kernels_ready():
            self.progress(0, int(self.generations), "compiling the SNGP kernels (once; cached for "
                          "later runs)")
        monitor = None
        if val is not None and self.early_stop_window:
            held = popmod.terminal_rows(X_all[val], int(val.sum()), names, prior_syms, prior_exprs,
                                  prior_labels)
            monitor = popmod.holdout(template, held, y_all[val])
        import_symbolic_side()
        result = run_search(template, problem, generations=int(self.generations),
                            n_epochs=int(self.n_epochs), n_threads=int(self.n_threads),
                            identity_steps=int(self.identity_steps), gamma=float(self.gamma),
                            rng=rng, progress=self.progress,
                            early_stop_window=self.early_stop_window,
                            early_stop_margin=float(self.early_stop_margin), monitor=monitor,
                            workers=int(self.n_jobs))

        self._names = names
        self._prior_syms = prior_syms
        self._prior_labels = prior_labels
        self._prior_exprs = dict(zip(prior_syms, prior_exprs))
        self._problem = problem
        self._template = template

        # final model
        if constrained and result.archive:
            chosen = result.archive[best_index(result.archive, lambda r: r[0], lambda r: r[1],
                                               lambda r: r[1] < self.gamma)]
            final = self._population_from_links(chosen[2], chosen[3])
            self.qualified_ = bool(chosen[1] < self.gamma)
            if not self.qualified_:
                log.warning("no model met the constraint error threshold gamma=%g; returning the "
                            "lowest-e_c model (e_c=%g)", self.gamma, chosen[1])
        else:
            final = result.best
            self.qualified_ = True
        model, ed, ec = self._build_model(final, y, cs if constrained else None,
                                          None if val is None else (X_all, y_all, val))
        self.model_ = model
        self._cs_train = cs
        self.rmse_train_ = ed
        self.constraint_rmse_train_ = ec if constrained else float("nan")
        if constrained and self.qualified_ and not ec < self.gamma:
            self.qualified_ = False
        self._rendered = None
        self.intercept_ = model.intercept
        self.archive_ = self._archive(result.archive) if constrained else [
            ArchiveEntry(ed, float("nan"), lambda: self.equation_)]
        self.generations_ = int(result.generations)
        self.stopped_early_ = bool(result.stopped_early)
        self.seed_ = seed
        self.search_stats_ = {
            "search_s": result.wall_s,
            "search_cpu_s": result.cpu_s,
            "generations": int(result.generations),
            "generations_budget": int(result.budget),
            "stopped_early": bool(result.stopped_early),
            "early_stop_window": int(self.early_stop_window or 0),
            "early_stop_margin": float(self.early_stop_margin),
            "early_stop_signal": ("held-out rmse" if monitor is not None else
                                  "training error" if self.early_stop_window else "none"),
            "node_evaluations": int(result.evaluations),
            "accepted": int(result.accepted),
            "failed_fits": int(result.failed_fits),
            "least_squares_fits": int(result.solves),
            "generations_per_s": result.generations / result.wall_s if result.wall_s > 0 else float("nan"),
            "node_evaluations_per_s": result.evaluations / result.wall_s if result.wall_s > 0 else float("nan"),
        }
        self.n_features_in_ = len(names)
        self.feature_names_in_ = tuple(names)
        self.wall_s_ = time.perf_counter() - t_start
        return self

    # -- helpers for fit -----------------------------------------------------------------------
    @staticmethod
    def _feature_names(feature_names, d: int) -> tuple[str, ...]:
        if feature_names is None:
            return tuple(f"x{i}" for i in range(d))
        names = tuple(str(n) for n in feature_names)
        if len(names) != d:
            raise ConfigError(f"feature_names has {len(names)} names but X has {d} columns")
        if len(set(names)) != len(names):
            raise ConfigError(f"feature_names must be unique, got {list(names)}")
        for n in names:
            if not n.isidentifier() or n in _RESERVED:
                raise ConfigError(f"feature name {n!r} is not usable as a symbol "
                                  "(use letters, digits and _; not pi, e, E, I, N, S, O, Q)")
        return names

    @staticmethod
    def _priors(priors, prior_names, names):
        if priors is None:
            priors = ()
        if isinstance(priors, str) or is_sympy(priors):
            priors = (priors,)
        priors = list(priors)
        if prior_names is not None:
            prior_names = [str(p) for p in prior_names]
            if len(prior_names) != len(priors):
                raise ConfigError(f"prior_names has {len(prior_names)} names for {len(priors)} priors")
        if not priors:
            return [], [], {}
        import sympy as sp

        exprs, syms, labels = [], [], {}
        for i, p in enumerate(priors):
            label = prior_names[i] if prior_names else f"prior{i + 1}"
            if isinstance(p, str):
                expr = _expressions.parse_expression(p, names, what=f"prior {label!r}")
            elif isinstance(p, sp.Basic):
                unknown = sorted(s.name for s in p.free_symbols if s.name not in names)
                if unknown:
                    raise MissingSignalError(unknown[0], names, where=f"prior {label!r}")
                expr = p.xreplace({s: _expressions.symbol(s.name) for s in p.free_symbols})
            else:
                raise ConfigError(f"prior {label!r} must be a string or a sympy expression, "
                                  f"got {type(p).__name__}")
            clean = re.sub(r"\W+", "_", label).strip("_")
            sym = f"P{i + 1}" if not prior_names or not clean else f"P{i + 1}_{clean}"
            while sym in names or sym in syms:
                sym += "_"
            exprs.append(expr)
            syms.append(sym)
            labels[sym] = label
        return exprs, syms, labels

    @staticmethod
    def _constraints(constraints, names):
        if constraints is None:
            return None
        if not isinstance(constraints, ConstraintSamples):
            raise ConfigError(f"constraints must be ConstraintSamples, got {type(constraints).__name__}")
        if len(constraints) == 0:
            return None
        missing = [n for n in names if n not in constraints.input_names]
        if missing:
            raise MissingSignalError(missing[0], constraints.input_names, where="the constraint samples")
        cs = constraints.reorder(names)
        if not np.isfinite(cs.X).all():
            raise DataError("constraint samples must be finite")
        return cs

    def _population_from_links(self, a, b) -> Population:
        pop = self._template.copy()
        popmod.load_terminals(pop, self._problem)
        pop.a[:] = a
        pop.b[:] = b
        popmod.evaluate_all(pop, self._problem)
        ok = popmod.solve(pop, self._problem)
        if not ok:
            pop.obj[:2] = np.inf
        return pop

    def _node_exprs(self, pop: Population):
        return node_exprs(pop, self._names, self._prior_syms)

    def _build_model(self, pop: Population, y, cs, validation=None):
        """Refit the final population's features, prune dead ones, return (model, e_d, e_c).

        ``validation``: ``(X_all, y_all, mask)`` with the held-out rows of ``prune="validation"``;
        then e_d is over all training rows."""
        nt = y.size
        n_prior = len(self._prior_syms)
        feat_nodes = [int(c) for c, bta in zip(pop.cols, pop.beta)
                      if c >= int(pop.lay[K.L_ID]) and bta != 0.0]
        prior_nodes = list(range(int(pop.lay[K.L_TAIL]) - n_prior, int(pop.lay[K.L_TAIL])))
        cols = prior_nodes + feat_nodes
        A = np.column_stack([np.ones(pop.V.shape[2])] + [pop.current(c) for c in cols])
        At, Ac = A[:nt], A[nt:]
        constrained = cs is not None

        def fit(keep):
            beta = _lstsq(At[:, keep], y)
            ed = rmse(y, At[:, keep] @ beta)
            ec = constraint_rmse(Ac[:, keep] @ beta, cs) if constrained else 0.0
            return beta, ed, ec

        keep = list(range(A.shape[1]))
        beta, ed, ec = fit(keep)
        tiny = 1e-12 * (float(np.std(y)) + 1e-300)
        for j in range(1 + n_prior, A.shape[1]):     # evolved features only
            trial = [k for k in keep if k != j]
            b2, ed2, ec2 = fit(trial)
            if ed2 <= ed * (1 + PRUNE_RTOL) + tiny and (not constrained or ec2 <= ec * (1 + PRUNE_RTOL) + tiny):
                keep, beta, ed, ec = trial, b2, ed2, ec2
        node_expr = self._node_exprs(pop)
        if validation is not None:
            keep, beta, ed, ec = self._prune_validation(validation, A, At, Ac, y, cols, keep, ec,
                                                        n_prior, node_expr, cs)
        terms, coefs = [], []
        intercept = 0.0
        for k, bta in zip(keep, beta):
            if k == 0:
                intercept = float(bta)
            else:
                terms.append(node_expr(cols[k - 1]))
                coefs.append(float(bta))
        model = _model.SymbolicModel(self._names, terms, coefs, intercept,
                              {s: self._prior_exprs[s] for s in self._prior_syms},
                              dict(self._prior_labels))
        return model, ed, (ec if constrained else float("nan"))

    def _prune_validation(self, validation, A, At, Ac, y, cols, keep, ec, n_prior, node_expr, cs):
        """Backward elimination of evolved features on the held-out rows, then a refit of the
        kept columns on all training rows. Returns (keep, beta, e_d over all rows, e_c)."""
        X_all, y_all, val = validation
        env = {n: X_all[val, i] for i, n in enumerate(self._names)}
        for sym, expr in self._prior_exprs.items():   # as SymbolicModel.predict evaluates them
            env[sym] = _expressions.compile_expression(expr, self._names)(env)
        names = list(self._names) + list(self._prior_exprs)
        Av = np.empty((int(val.sum()), A.shape[1]))
        Av[:, 0] = 1.0
        for j, c in enumerate(cols, start=1):
            with np.errstate(all="ignore"):
                Av[:, j] = _expressions.compile_expression(node_expr(c), names)(env)
        if not np.isfinite(Av).all():   # a feature undefined on the held-out rows must go
            keep = [k for k in keep if k <= n_prior or np.isfinite(Av[:, k]).all()]
        yv = y_all[val]
        constrained = cs is not None

        def score(kp):
            beta = _lstsq(At[:, kp], y)
            ev = rmse(yv, Av[:, kp] @ beta)
            ecv = constraint_rmse(Ac[:, kp] @ beta, cs) if constrained else 0.0
            return ev, ecv

        cur, _ = score(keep)
        while True:
            best = None
            for j in keep[1 + n_prior:]:
                trial = [k for k in keep if k != j]
                ev, ec2 = score(trial)
                if constrained and not (ec2 < self.gamma or ec2 <= ec):
                    continue
                if best is None or ev < best[0]:
                    best = (ev, trial)
            if best is None or best[0] > cur * (1 + VALIDATION_MIN_GAIN):
                break
            cur, keep = best
        Afull = np.empty((y_all.size, A.shape[1]))
        Afull[~val], Afull[val] = At, Av
        beta = _lstsq(Afull[:, keep], y_all)
        ed = rmse(y_all, Afull[:, keep] @ beta)
        ec = constraint_rmse(Ac[:, keep] @ beta, cs) if constrained else 0.0
        return keep, beta, ed, ec

    def _rendered_attr(self, name: str):
        """The simplified forms are built with sympy on first use (most runs of a study or of
        identify are never shown), then kept."""
        self._check_fitted()
        if self._rendered is None:
            self._rendered = render(self.model_, self._prior_syms, self._prior_labels,
                                    self._prior_exprs, self.simplify_s)
        return self._rendered[name]

    equation_ = property(lambda self: self._rendered_attr("equation_"),
                         doc="The fitted equation as text (simplified, rounded), built on first use.")
    expr_ = property(lambda self: self._rendered_attr("expr_"),
                     doc="The fitted model as a sympy expression with the priors written out.")
    expr_raw_ = property(lambda self: self._rendered_attr("expr_raw_"),
                         doc="The fitted model before simplification (sympy).")
    latex_ = property(lambda self: self._rendered_attr("latex_"), doc="The equation in LaTeX.")
    coef_ = property(lambda self: self._rendered_attr("coef_"),
                     doc="Coefficient of each evolved term, keyed by the simplified term's text.")
    prior_coef_ = property(lambda self: self._rendered_attr("prior_coef_"),
                           doc="Coefficient of each prior feature, keyed by its name.")

    def _archive(self, archive) -> list["ArchiveEntry"]:
        return [ArchiveEntry(ed, ec, lambda a=a, b=b: self._archive_equation(a, b))
                for ed, ec, a, b in archive]

    def _archive_equation(self, a, b) -> str:
        return links_equation(self._population_from_links(a, b), self._names, self._prior_syms)

    # -- use -----------------------------------------------------------------------------------
    def _check_fitted(self):
        if not hasattr(self, "model_"):
            raise NotFittedError("This SNGPRegressor is not fitted yet; call fit(X, y, ...) first")

    def predict(self, X) -> np.ndarray:
        self._check_fitted()
        return self.model_.predict(X)

    def rmse(self, X, y) -> float:
        y = np.asarray(y, dtype=float).ravel()
        return rmse(self.predict(X), y)

    def constraint_rmse(self, cs: ConstraintSamples) -> float:
        """e_c of the fitted model on constraint samples ``cs`` (e.g. the held-out test draw)."""
        self._check_fitted()
        cs = self._constraints(cs, self.feature_names_in_)
        if cs is None:
            return float("nan")
        return constraint_rmse(self.predict(cs.X), cs)

    def to_dict(self) -> dict:
        self._check_fitted()
        d = self.model_.to_dict()
        d.update({"equation": self.equation_, "rmse_train": self.rmse_train_,
                  "constraint_rmse_train": self.constraint_rmse_train_, "qualified": self.qualified_,
                  "prior_coef": dict(self.prior_coef_), "seed": self.seed_,
                  "generations": self.generations_, "stopped_early": self.stopped_early_,
                  "params": {k: v for k, v in self.get_params().items() if k not in _HOW}})
        d["params"]["functions"] = list(d["params"]["functions"])
        return d


def _validation_rows(n: int, fraction: float):
    """Held-out rows for ``prune="validation"``: 8 contiguous blocks, ``round(fraction * 8)`` of
    them held out, spread from block 1 on (blocks 1 and 4, 0-based, for a quarter), so the held-out
    part spans the flight; None when too few rows."""
    n_blocks = 8
    n_val_blocks = max(1, int(round(fraction * n_blocks)))
    if n < 40 * n_blocks // n_val_blocks or n < 80:
        log.warning("prune='validation' needs at least 80 training samples (got %d): "
                    "pruning only exactly dead features", n)
        return None
    block = block_ids(np.arange(n, dtype=float), np.zeros(n, int), n_blocks)   # contiguous, equal counts
    held = set(np.round(np.linspace(1, n_blocks - 1, n_val_blocks, endpoint=False)).astype(int).tolist())
    return np.isin(block, sorted(held))



#: parameters that change how a fit runs, never its result: not recorded in to_dict
_HOW = ("progress", "n_jobs")
#: the estimator's parameters and their defaults, read from its signature (their one home)
_PARAMS = {name: p.default for name, p in inspect.signature(SNGPRegressor.__init__).parameters.items()
           if p.kind is inspect.Parameter.KEYWORD_ONLY}


#: the smallest integer each integer parameter takes. max_depth counts the identity level of a
#: feature slot: at depth 1 every feature is an input or constant as it stands (no operator can
#: be placed), so the search is a linear fit of the inputs; 2 is the first depth with a function
_MIN_INT = {"population_size": 20, "generations": 1, "n_features": 1, "max_depth": 2,
            "n_epochs": 1, "n_threads": 1, "n_jobs": 1, "identity_steps": 0}


def _check_param(name: str, v, owner: str) -> None:
    """Raise ConfigError when ``v`` is not a valid value of engine parameter ``name``."""
    def bad(expected):
        raise ConfigError(f"The '{name}' parameter of {owner} must be {expected}. Got {v!r} instead.")

    def number(x) -> bool:
        return not isinstance(x, bool) and isinstance(x, (int, float, np.integer, np.floating))

    if name in _MIN_INT:
        lo = _MIN_INT[name]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            bad(f"an int >= {lo}")
    elif name == "functions":
        if isinstance(v, str) or not isinstance(v, Sequence) or not v:
            bad("a non-empty sequence of operator names")
        for f in v:
            if f not in operator_names():
                raise ConfigError(f"The 'functions' parameter of {owner} has an unknown operator "
                                  f"{f!r}{did_you_mean(str(f), operator_names())}; known: "
                                  f"{', '.join(operator_names())}")
    elif name == "gamma":
        if not number(v) or not v > 0 or not math.isfinite(v):
            bad("a positive finite number")
    elif name == "seed":
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0):
            bad("None or an int >= 0")
    elif name == "progress":
        if v is not None and not callable(v):
            bad("None or a callable(done, total, message)")
    elif name == "simplify_s":
        if not number(v) or not 0 <= v < math.inf:
            bad("a finite number >= 0 (seconds)")
    elif name == "prune":
        check_choice("prune", v, ("exact", "validation"), owner=owner)
    elif name == "validation_fraction":
        if not number(v) or not 0.05 <= v <= 0.5:
            bad("a number in [0.05, 0.5]")
    elif name == "early_stop_window":
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0):
            bad("None or an int >= 0 (generations; 0 or None: no early stop)")
    elif name == "early_stop_margin":
        if not number(v) or not 0 <= v < 1:
            bad("a number in [0, 1) (relative improvement)")
