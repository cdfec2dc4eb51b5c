"""SNGPRegressor: the estimator-style front of the engine (validation, search, model building).

``__init__`` only stores keyword parameters (unknown names are rejected with a suggestion);
``fit`` validates, runs the compiled search (:mod:`droneid.sngp.search`), prunes dead features,
simplifies the equation with sympy under a time limit and fills the ``*_`` attributes.

sympy is imported only where the symbolic side begins (prior expressions, the final model, its
rendering): a fit without priors runs its search before sympy is imported, and imports sympy in
a background thread meanwhile (the search kernels release the GIL), so a fresh process such as
``droneid fit`` does not wait for the import on top of the search.
"""
from __future__ import annotations

import logging
import inspect
import math
import re
import signal
import sys
import threading
import time
from collections.abc import Mapping, Sequence

import numpy as np

from ..constraint_samples import ConstraintSamples, constraint_rmse
from ..errors import (ConfigError, DataError, MissingSignalError, NotFittedError, check_choice,
                      did_you_mean)
from ..numerics import lstsq as _lstsq
from ..numerics import rmse
from . import kernels as K
from .kernels import kernels_ready
from . import population as popmod
from .operators import CONST, IDENT, DEFAULT_FUNCTIONS, by_code, names as operator_names
from .population import Population, Problem
from .selection import best_index
from .search import run_search

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
    ``n_threads`` (search threads per epoch, run one after the other), ``seed`` (None: drawn),
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
    ``generations``, the paper's protocol). ``generations_`` reports the generations run and
    ``stopped_early_`` whether the window ended the search.
    """

    def __init__(self, *, functions=DEFAULT_FUNCTIONS, population_size=500, generations=60000,
                 n_features=10, max_depth=7, gamma=0.05, n_epochs=30, n_threads=2, seed=None,
                 progress=None, identity_steps=100, simplify_s=0.5, prune="exact",
                 validation_fraction=0.25, early_stop_window=10000, early_stop_margin=0.001,
                 **unknown):
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
    def _validate_params(self) -> None:
        def bad(name, expected, value):
            raise ConfigError(f"The '{name}' parameter of SNGPRegressor must be {expected}. "
                              f"Got {value!r} instead.")

        def integer(name, lo):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                bad(name, f"an int >= {lo}", v)

        funcs = self.functions
        if isinstance(funcs, str) or not isinstance(funcs, Sequence) or not funcs:
            bad("functions", "a non-empty sequence of operator names", funcs)
        for f in funcs:
            if f not in operator_names():
                raise ConfigError(f"The 'functions' parameter of SNGPRegressor has an unknown "
                                  f"operator {f!r}{did_you_mean(str(f), operator_names())}; "
                                  f"known: {', '.join(operator_names())}")
        integer("population_size", 20)
        integer("generations", 1)
        integer("n_features", 1)
        integer("max_depth", 1)
        integer("n_epochs", 1)
        integer("n_threads", 1)
        integer("identity_steps", 0)
        if isinstance(self.gamma, bool) or not isinstance(self.gamma, (int, float)) \
                or not self.gamma > 0 or not math.isfinite(self.gamma):
            bad("gamma", "a positive finite number", self.gamma)
        if self.seed is not None and (isinstance(self.seed, bool)
                                      or not isinstance(self.seed, (int, np.integer)) or self.seed < 0):
            bad("seed", "None or an int >= 0", self.seed)
        if self.progress is not None and not callable(self.progress):
            bad("progress", "None or a callable(done, total, message)", self.progress)
        if not isinstance(self.simplify_s, (int, float)) or self.simplify_s < 0:
            bad("simplify_s", "a number >= 0 (seconds)", self.simplify_s)
        check_choice("prune", self.prune, ("exact", "validation"), owner="SNGPRegressor")
        v = self.validation_fraction
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.05 <= v <= 0.5:
            bad("validation_fraction", "a number in [0.05, 0.5]", v)
        w = self.early_stop_window
        if w is not None and (isinstance(w, bool) or not isinstance(w, (int, np.integer)) or w < 0):
            bad("early_stop_window", "None or an int >= 0 (generations; 0 or None: no early stop)", w)
        m = self.early_stop_margin
        if isinstance(m, bool) or not isinstance(m, (int, float)) or not 0 <= m < 1:
            bad("early_stop_margin", "a number in [0, 1) (relative improvement)", m)

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
        terminals = _terminal_rows(Xall, y.size, names, prior_syms, prior_exprs, prior_labels)
        yc = y - y.mean()
        if constrained:
            ckind = np.asarray(cs.kind, dtype=np.int64)
            cbound = np.asarray(cs.bound, dtype=np.float64)
        else:
            ckind, cbound = np.zeros(0, dtype=np.int64), np.zeros(0)
        problem = Problem(y=y.copy(), yc=yc, syy=float(yc @ yc), ckind=ckind, cbound=cbound,
                          terminals=terminals)
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
            held = _terminal_rows(X_all[val], int(val.sum()), names, prior_syms, prior_exprs,
                                  prior_labels)
            monitor = popmod.holdout(template, held, y_all[val])
        _import_symbolic_side()
        result = run_search(template, problem, generations=int(self.generations),
                            n_epochs=int(self.n_epochs), n_threads=int(self.n_threads),
                            identity_steps=int(self.identity_steps), gamma=float(self.gamma),
                            rng=rng, progress=self.progress,
                            early_stop_window=self.early_stop_window,
                            early_stop_margin=float(self.early_stop_margin), monitor=monitor)

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
        if isinstance(priors, str) or _is_sympy(priors):
            priors = (priors,)
        priors = list(priors)
        if prior_names is not None:
            prior_names = [str(p) for p in prior_names]
            if len(prior_names) != len(priors):
                raise ConfigError(f"prior_names has {len(prior_names)} names for {len(priors)} priors")
        if not priors:
            return [], [], {}
        import sympy as sp

        from ..expressions import parse_expression, symbol
        exprs, syms, labels = [], [], {}
        for i, p in enumerate(priors):
            label = prior_names[i] if prior_names else f"prior{i + 1}"
            if isinstance(p, str):
                expr = parse_expression(p, names, what=f"prior {label!r}")
            elif isinstance(p, sp.Basic):
                unknown = sorted(s.name for s in p.free_symbols if s.name not in names)
                if unknown:
                    raise MissingSignalError(unknown[0], names, where=f"prior {label!r}")
                expr = p.xreplace({s: symbol(s.name) for s in p.free_symbols})
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
        import sympy as sp

        from ..expressions import symbol
        consts = (sp.Integer(0), sp.Rational(1, 2), sp.Integer(1), sp.Integer(2), sp.Integer(3), sp.pi)
        lay = pop.lay
        head_end, tail0 = int(lay[K.L_HEAD]), int(lay[K.L_TAIL])
        terminals = [symbol(n) for n in self._names] + [symbol(s) for s in self._prior_syms]
        memo: dict[int, "sp.Expr"] = {}

        def expr(n: int) -> "sp.Expr":
            if n in memo:
                return memo[n]
            code = int(pop.op[n])
            if code == CONST:
                e = consts[n] if n < len(consts) else sp.Float(pop.cval[n])
            elif n < head_end:
                e = sp.Float(float(pop.current(n)[0]))
            elif n < tail0:
                e = terminals[n - head_end]
            elif code == IDENT:
                e = expr(int(pop.a[n]))
            else:
                op = by_code(code)
                args = [expr(int(pop.a[n]))] + ([expr(int(pop.b[n]))] if op.arity == 2 else [])
                e = op.sympy(*args)
            memo[n] = e
            return e
        return expr

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
        from .model import SymbolicModel
        model = SymbolicModel(self._names, terms, coefs, intercept,
                              {s: self._prior_exprs[s] for s in self._prior_syms},
                              dict(self._prior_labels))
        return model, ed, (ec if constrained else float("nan"))

    def _prune_validation(self, validation, A, At, Ac, y, cols, keep, ec, n_prior, node_expr, cs):
        """Backward elimination of evolved features on the held-out rows, then a refit of the
        kept columns on all training rows. Returns (keep, beta, e_d over all rows, e_c)."""
        from ..expressions import compile_expression
        X_all, y_all, val = validation
        env = {n: X_all[val, i] for i, n in enumerate(self._names)}
        for sym, expr in self._prior_exprs.items():   # as SymbolicModel.predict evaluates them
            env[sym] = compile_expression(expr, self._names)(env)
        names = list(self._names) + list(self._prior_exprs)
        Av = np.empty((int(val.sum()), A.shape[1]))
        Av[:, 0] = 1.0
        for j, c in enumerate(cols, start=1):
            with np.errstate(all="ignore"):
                Av[:, j] = compile_expression(node_expr(c), names)(env)
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

    def _render(self, model: "SymbolicModel") -> dict:
        """Simplified forms of the model: equation_, expr_, expr_raw_, latex_, coef_, prior_coef_."""
        import sympy as sp

        from ..expressions import symbol
        from .model import round_expr, to_text
        deadline = time.perf_counter() + float(self.simplify_s)
        prior_set = {symbol(s) for s in self._prior_syms}
        simple_terms = []
        for t in model.terms:
            left = deadline - time.perf_counter()
            simple_terms.append(_guarded_simplify(t, left) if t not in prior_set else t)
        coef = {}
        prior_coef = {self._prior_labels[s]: 0.0 for s in self._prior_syms}
        display = sp.Float(model.intercept)
        for t, st, c in zip(model.terms, simple_terms, model.coefs):
            if t in prior_set:
                prior_coef[self._prior_labels[t.name]] = c
            else:
                key = to_text(st)
                coef[key] = coef.get(key, 0.0) + c
            display = display + sp.Float(c) * st
        shown = round_expr(display)
        return {"coef_": coef, "prior_coef_": prior_coef,
                "expr_raw_": model.expression(expand_priors=True),
                "expr_": display.xreplace({symbol(s): e for s, e in self._prior_exprs.items()}),
                "equation_": to_text(shown), "latex_": sp.latex(shown)}

    def _rendered_attr(self, name: str):
        """The simplified forms are built with sympy on first use (most runs of a study or of
        identify are never shown), then kept."""
        self._check_fitted()
        if self._rendered is None:
            self._rendered = self._render(self.model_)
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
        import sympy as sp

        from .model import round_expr, to_text
        pop = self._population_from_links(a, b)
        node_expr = self._node_exprs(pop)
        expr = sp.Integer(0)
        for c, bta in zip(pop.cols, pop.beta):
            if c == -1:
                expr += sp.Float(float(bta))
            elif c >= 0 and bta != 0.0:
                expr += sp.Float(float(bta)) * node_expr(int(c))
        return to_text(round_expr(expr))

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
                  "params": {k: v for k, v in self.get_params().items() if k != "progress"}})
        d["params"]["functions"] = list(d["params"]["functions"])
        return d


class ArchiveEntry(Mapping):
    """One non-dominated model of the constrained search: a read-only mapping with the keys
    ``rmse_train``, ``constraint_rmse_train`` and ``equation``. The equation is built with sympy
    only when first read (a run archives up to 64 models and most callers read the errors)."""

    _KEYS = ("rmse_train", "constraint_rmse_train", "equation")

    def __init__(self, rmse_train: float, constraint_rmse_train: float, equation):
        self._values = {"rmse_train": float(rmse_train),
                        "constraint_rmse_train": float(constraint_rmse_train)}
        self._equation = equation

    def __getitem__(self, key):
        if key == "equation" and key not in self._values:
            self._values[key] = self._equation()
        if key not in self._KEYS:
            raise KeyError(key)
        return self._values[key]

    def __iter__(self):
        return iter(self._KEYS)

    def __len__(self) -> int:
        return len(self._KEYS)

    def __repr__(self) -> str:
        return f"ArchiveEntry({dict(self)!r})"


def _terminal_rows(X, n_train, names, prior_syms, prior_exprs, prior_labels) -> np.ndarray:
    """The terminal rows of the node cache: the inputs, then each prior evaluated on ``X``
    (rows ``n_train`` on are constraint samples); a prior that is not finite is a DataError."""
    cols = {n: X[:, i] for i, n in enumerate(names)}
    prior_vals = []
    for sym, expr in zip(prior_syms, prior_exprs):
        from ..expressions import compile_expression
        v = compile_expression(expr, names)(cols)
        if not np.isfinite(v[:n_train]).all():
            raise DataError(f"prior {prior_labels[sym]!r} ({expr}) is not finite on "
                            f"{int((~np.isfinite(v[:n_train])).sum())} training samples")
        if not np.isfinite(v).all():
            raise DataError(f"prior {prior_labels[sym]!r} ({expr}) is not finite on some "
                            "constraint samples")
        prior_vals.append(v)
    rows = np.vstack([X.T] + [v[None, :] for v in prior_vals]) if prior_vals else X.T
    return np.ascontiguousarray(rows, dtype=np.float64)


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
    block = np.minimum(np.arange(n) * n_blocks // n, n_blocks - 1)
    held = set(np.round(np.linspace(1, n_blocks - 1, n_val_blocks, endpoint=False)).astype(int).tolist())
    return np.isin(block, sorted(held))



class _Timeout(Exception):
    pass


def _guarded_simplify(expr: "sp.Expr", seconds: float, max_ops: int = 60) -> "sp.Expr":
    """sympy.simplify with a wall-clock limit (SIGALRM in the main thread) and a size cap.

    Returns ``expr`` unchanged when it is too big, time runs out, or the result is not smaller.
    """
    import sympy as sp
    if seconds <= 0.01 or sp.count_ops(expr) > max_ops:
        return expr
    in_main = threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")
    if not in_main:
        if sp.count_ops(expr) > 15:
            return expr
        try:
            out = sp.simplify(expr)
        except Exception:   # noqa: BLE001 - simplification is optional
            return expr
    else:
        active = [True]

        def _alarm(signum, frame):
            if not active[0]:
                return
            # Raise only inside sympy: a signal can also land in foreign code run meanwhile
            # (a gc callback, a __del__) that would swallow the exception. Re-arm either way,
            # so the next tick ends the simplification if this one does not.
            signal.setitimer(signal.ITIMER_REAL, 0.02)
            where = frame.f_code.co_filename if frame is not None else ""
            if "sympy" in where or "mpmath" in where or where == __file__:
                raise _Timeout()
        old = signal.signal(signal.SIGALRM, _alarm)
        try:
            try:
                signal.setitimer(signal.ITIMER_REAL, min(seconds, 1.0))
                out = sp.simplify(expr)
            finally:
                active[0] = False
                signal.setitimer(signal.ITIMER_REAL, 0)
        except _Timeout:
            return expr
        except Exception:   # noqa: BLE001 - simplification is optional
            return expr
        finally:
            signal.signal(signal.SIGALRM, old if old is not None else signal.SIG_DFL)
    return out if sp.count_ops(out) <= sp.count_ops(expr) else expr


#: the estimator's parameters and their defaults, read from its signature (their one home)
_PARAMS = {name: p.default for name, p in inspect.signature(SNGPRegressor.__init__).parameters.items()
           if p.kind is inspect.Parameter.KEYWORD_ONLY}


def _is_sympy(obj) -> bool:
    """Whether ``obj`` is a sympy object (without importing sympy: none exists before it is)."""
    sympy = sys.modules.get("sympy")
    return sympy is not None and isinstance(obj, sympy.Basic)


def _import_symbolic_side() -> None:
    """Import the modules of the model and its rendering (sympy, ~0.3 s) in a background thread
    when nothing imported them yet: called as the search starts, whose kernels release the GIL,
    so the import overlaps the search instead of adding to it. Imports only: results are the
    same with or without it."""
    if "sympy" in sys.modules:
        return
    threading.Thread(target=_import_quietly, args=(f"{__package__}.model",),
                     name="droneid-import-sympy", daemon=True).start()


def _import_quietly(name: str) -> None:
    """Import ``name``, then run a full garbage collection: the import's many new objects would
    otherwise still be young when the equation is simplified (under a wall-clock budget), and
    the collections scanning them would eat into that budget (~0.07 s CPU measured); here, on
    the other core while the search runs, they cost the user nothing."""
    import gc
    import importlib
    try:
        importlib.import_module(name)
    except Exception:   # noqa: BLE001 - the main thread's own import of it reports the error
        return
    gc.collect()
