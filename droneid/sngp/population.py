"""The SNGP population as a small dataclass of numpy arrays (what the numba kernels work on).

Node layout, by ascending index (every link points to a lower index, so ascending order is a
valid evaluation order)::

    [constants | head block | variables | prior terminals | tail | identity nodes]
     0 .. 5      ~1/4 of the   one per     one per prior     F[j mod |F|]  nf - np feature
                 function      input                                       slots (arity 1)
                 slots
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from droneid.errors import DataError
from droneid.core.lazy import lazy_module
from droneid.core.numerics import rmse
from droneid.sngp import kernels as K
from droneid.sngp.operators import CONST, HEAD_OPERATORS, IDENT, VAR, by_name

_expressions = lazy_module("droneid.core.expressions")   # sympy: only with priors

CONSTANTS = (0.0, 0.5, 1.0, 2.0, 3.0, float(np.pi))


@dataclass
class Problem:
    """The data a run works on (read-only for the kernels)."""
    y: np.ndarray          # (nt,) training target
    yc: np.ndarray         # centred target
    syy: float
    ckind: np.ndarray      # (m,) constraint relation per constraint column
    cbound: np.ndarray     # (m,)
    terminals: np.ndarray  # (n_inputs + n_priors, nt + m): variable and prior rows


@dataclass
class Population:
    op: np.ndarray       # (P,) int64 operator code per node (fixed for the run)
    a: np.ndarray        # (P,) int64 first successor (-1: none)
    b: np.ndarray        # (P,) int64 second successor (-1: none / unary)
    cval: np.ndarray     # (P,) constant values; head nodes: proxy constant
    V: np.ndarray        # (2, P, N) cached outputs, two rows per node
    buf: np.ndarray      # (P,) int64 which row of V is current
    valid: np.ndarray    # (P,) uint8
    isconst: np.ndarray  # (P,) uint8 constant on the training columns
    fit: np.ndarray      # (P,) 1 - |corr(output, y)|
    lay: np.ndarray      # layout, see kernels.L_*
    beta: np.ndarray     # (nf + 1,) coefficients of the current model
    cols: np.ndarray     # (nf + 1,) node per coefficient (-1 intercept, -2 unused)
    obj: np.ndarray      # (3,) e_d, e_c, score
    gram: np.ndarray     # (1 + np + nid, 1 + np + nid) cached Gram matrix of [1 | priors | slots]
    rhs: np.ndarray      # (1 + np + nid,) cached [1 | priors | slots]^T y

    def copy(self) -> "Population":
        return Population(**{f.name: getattr(self, f.name).copy() for f in fields(self)})

    def copy_from(self, other: "Population") -> None:
        for f in fields(self):
            np.copyto(getattr(self, f.name), getattr(other, f.name))

    def current(self, n: int) -> np.ndarray:
        return self.V[self.buf[n], n]


def min_population(n_inputs: int, n_priors: int, n_identity: int) -> int:
    """The smallest population that holds the constants, one terminal per input and prior, the
    identity (feature) nodes and the two tail nodes a feature needs below it."""
    return len(CONSTANTS) + n_inputs + n_priors + n_identity + 2


def build_population(functions: tuple[str, ...], population_size: int, n_inputs: int,
                     n_priors: int, n_identity: int, max_depth: int, nt: int, n_columns: int,
                     constrained: bool, rng: np.random.Generator,
                     head_fraction: float = 0.25) -> Population:
    """An empty (unlinked) population with the layout fixed; links are drawn by the kernel."""
    n_const = len(CONSTANTS)
    slots = population_size - n_const - n_inputs - n_priors - n_identity
    n_head = int(round(head_fraction * slots))
    n_tail = slots - n_head
    if n_tail < 2:
        raise ValueError(f"population too small for the inputs, priors and features: at least "
                         f"{min_population(n_inputs, n_priors, n_identity)} for {n_inputs} inputs, "
                         f"{n_priors} priors and {n_identity} evolved features")
    head_end = n_const + n_head
    tail0 = head_end + n_inputs + n_priors
    id0 = tail0 + n_tail
    P = id0 + n_identity
    op = np.empty(P, dtype=np.int64)
    cval = np.zeros(P)
    op[:n_const] = CONST
    cval[:n_const] = CONSTANTS
    for j in range(n_head):
        op[n_const + j] = by_name(HEAD_OPERATORS[j % len(HEAD_OPERATORS)]).code
    cval[n_const:head_end] = rng.uniform(-10.0, 10.0, n_head)   # proxies for failed head nodes
    op[head_end:tail0] = VAR
    codes = [by_name(f).code for f in functions]
    for j in range(n_tail):
        op[tail0 + j] = codes[j % len(codes)]
    op[id0:] = IDENT
    lay = np.zeros(9, dtype=np.int64)
    lay[K.L_HEAD] = head_end
    lay[K.L_VAR] = head_end
    lay[K.L_TAIL] = tail0
    lay[K.L_ID] = id0
    lay[K.L_P] = P
    lay[K.L_NPRIOR] = n_priors
    lay[K.L_NT] = nt
    lay[K.L_DEPTH] = max_depth
    lay[K.L_MODE] = 1 if constrained else 0
    kmax = 1 + n_priors + n_identity
    return Population(
        op=op, a=np.full(P, -1, dtype=np.int64), b=np.full(P, -1, dtype=np.int64), cval=cval,
        V=np.zeros((2, P, n_columns)), buf=np.zeros(P, dtype=np.int64),
        valid=np.zeros(P, dtype=np.uint8), isconst=np.zeros(P, dtype=np.uint8), fit=np.ones(P),
        lay=lay, beta=np.zeros(kmax), cols=np.full(kmax, -2, dtype=np.int64), obj=np.zeros(3),
        gram=np.zeros((kmax, kmax)), rhs=np.zeros(kmax))


def load_terminals(pop: Population, problem: Problem) -> None:
    t0 = int(pop.lay[K.L_VAR])
    nterm = problem.terminals.shape[0]
    pop.V[0, t0:t0 + nterm] = problem.terminals
    pop.V[1, t0:t0 + nterm] = problem.terminals


def init(pop: Population, problem: Problem, seed: int) -> bool:
    return bool(K.init_population(seed, pop.op, pop.a, pop.b, pop.cval, pop.V, pop.buf, pop.valid,
                                  pop.isconst, pop.fit, pop.lay, problem.y, problem.yc, problem.syy,
                                  problem.ckind, problem.cbound, pop.beta, pop.cols, pop.obj,
                                  pop.gram, pop.rhs))


def evaluate_all(pop: Population, problem: Problem) -> None:
    K.evaluate_all(pop.op, pop.a, pop.b, pop.cval, pop.V, pop.buf, pop.valid, pop.isconst,
                   pop.fit, pop.lay, problem.yc, problem.syy)


def solve(pop: Population, problem: Problem) -> bool:
    """Rebuild the Gram cache and refit the model of ``pop`` (after evaluate_all)."""
    return bool(K.solve_fresh(pop.op, pop.V, pop.buf, pop.valid, pop.isconst, pop.fit, pop.lay,
                              problem.y, problem.ckind, problem.cbound, pop.beta, pop.cols,
                              pop.obj, pop.gram, pop.rhs))


def run(pop: Population, problem: Problem, seed: int, n_gens: int, identity_only: bool,
        weight: float, archive, stats: np.ndarray) -> None:
    arch_obj, arch_a, arch_b, arch_n = archive
    K.run_chunk(seed, n_gens, identity_only, weight, pop.op, pop.a, pop.b, pop.cval, pop.V,
                pop.buf, pop.valid, pop.isconst, pop.fit, pop.lay, problem.y, problem.yc,
                problem.syy, problem.ckind, problem.cbound, pop.beta, pop.cols, pop.obj,
                pop.gram, pop.rhs, arch_obj, arch_a, arch_b, arch_n, stats)


def terminal_rows(X, n_train, names, prior_syms, prior_exprs, prior_labels) -> np.ndarray:
    """The terminal rows of the node cache: the inputs, then each prior evaluated on ``X``
    (rows ``n_train`` on are constraint samples); a prior that is not finite is a DataError."""
    cols = {n: X[:, i] for i, n in enumerate(names)}
    prior_vals = []
    for sym, expr in zip(prior_syms, prior_exprs):   # sympy: only with priors
        v = _expressions.compile_expression(expr, names)(cols)
        if not np.isfinite(v[:n_train]).all():
            raise DataError(f"prior {prior_labels[sym]!r} ({expr}) is not finite on "
                            f"{int((~np.isfinite(v[:n_train])).sum())} training samples")
        if not np.isfinite(v).all():
            raise DataError(f"prior {prior_labels[sym]!r} ({expr}) is not finite on some "
                            "constraint samples")
        prior_vals.append(v)
    rows = np.vstack([X.T] + [v[None, :] for v in prior_vals]) if prior_vals else X.T
    return np.ascontiguousarray(rows, dtype=np.float64)


def holdout(template: Population, terminals: np.ndarray, y: np.ndarray):
    """A callable(pop) -> RMSE of ``pop``'s current model on held-out rows.

    ``terminals``: (n_inputs + n_priors, n_rows) the variable and prior rows of the held-out
    samples; ``y``: their target. The links of ``pop`` are copied into a population sized for
    these rows and evaluated there; the coefficients are ``pop``'s (fitted on the search rows).
    A model that is not finite on a held-out row scores inf.
    """
    n_rows = terminals.shape[1]
    shadow = template.copy()
    shadow.V = np.zeros((2, shadow.V.shape[1], n_rows))
    shadow.lay[K.L_NT] = n_rows
    shadow.lay[K.L_MODE] = 0
    prob = Problem(y=y, yc=np.zeros(n_rows), syy=0.0, ckind=np.zeros(0, dtype=np.int64),
                   cbound=np.zeros(0), terminals=terminals)
    load_terminals(shadow, prob)

    def error(pop: Population) -> float:
        np.copyto(shadow.a, pop.a)
        np.copyto(shadow.b, pop.b)
        evaluate_all(shadow, prob)
        pred = np.full(n_rows, 0.0)
        for c, beta in zip(pop.cols, pop.beta):
            if c == -1:
                pred += beta
            elif c >= 0 and beta != 0.0:
                pred += beta * shadow.current(int(c))
        with np.errstate(all="ignore"):
            e = rmse(pred, y)
        return e if math.isfinite(e) else math.inf
    return error
