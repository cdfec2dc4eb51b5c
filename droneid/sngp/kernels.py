"""numba kernels of the SNGP search: node evaluation, mutation, least squares, (1+1) acceptance.

Everything that runs once per generation lives here and is compiled: Python only calls
:func:`init_population` and :func:`run_chunk` (a few hundred to a few thousand generations per
call) and copies populations between threads. The arrays are described in
:class:`droneid.sngp.population.Population`.

Value cache: ``V[2, P, N]`` holds each node's output over the N columns (training samples,
then constraint samples). Every node owns two rows; ``buf[n]`` says which one is current. A
re-evaluated node writes into its other row and flips ``buf``; rejecting the candidate flips
the dirtied nodes back, so nothing is ever copied per generation (the undo log is the list of
changed links and dirtied nodes).

The two long-running entry kernels (:func:`init_population`, :func:`run_chunk`) release the GIL
(``nogil``), so another thread can work meanwhile (the estimator imports sympy for the equation
while the search runs). nogil changes only the call wrapper, not the compiled code.

``lay`` (int64) holds the layout: see the ``L_*`` indices below.
"""
from __future__ import annotations

import logging
import math
import sys

import numpy as np
from numba import njit

from droneid.sngp.operators import CONST, DIV_EPS, IDENT, MAX_ABS, by_name

_log = logging.getLogger(__name__)

# layout indices into ``lay``
L_HEAD, L_VAR, L_TAIL, L_ID, L_P, L_NPRIOR, L_NT, L_DEPTH, L_MODE = range(9)
# objective slots in ``obj``
O_ED, O_EC, O_SCORE = 0, 1, 2
# stats slots
S_EVALS, S_ACCEPT, S_GENS, S_FAILED, S_SOLVES = 0, 1, 2, 3, 4
N_STATS = 5

ADD = by_name("add").code
SUB = by_name("sub").code
MUL = by_name("mul").code
SQUARE = by_name("square").code
CUBE = by_name("cube").code
SIN = by_name("sin").code
COS = by_name("cos").code
NEG = by_name("neg").code
DIV = by_name("div").code
SQRTABS = by_name("sqrtabs").code
TAN = by_name("tan").code
ABS = by_name("abs").code
EXP = by_name("exp").code
TANH = by_name("tanh").code

P_TERMINAL = 0.25   # probability that a new link goes to a terminal
P_HEAD = 0.1        # probability that a mutation hits the head block
TOURNAMENT = 3
MAX_MUTATIONS = 10
PIVOT_TOL = 1e-11   # Cholesky: drop a column whose normalised Schur complement is below this
CONST_TOL = 1e-12   # a node is constant on the training data when var <= CONST_TOL * (1 + mean^2)

#: No fastmath: reassociation would make sums depend on how LLVM inlined and vectorised a loop,
#: and then a freshly compiled kernel and a cached one could disagree in the last bit (and the
#: search would diverge). Reductions use four explicit accumulators instead, which is both
#: deterministic and vectorisable.
FM = False
#: Our sin/cos are exact to ~1 ulp only after Cody-Waite reduction for |x| <= this; beyond it
#: the kernel falls back to libm.
TRIG_REDUCE_MAX = 1e5
_PIO2_1 = 1.57079632673412561417e+00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
# Taylor coefficients of sin r (r^3 ... r^21): on |r| <= pi/2 the next term is below 2e-18
_T3, _T5, _T7 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0
_T9, _T11, _T13 = 1.0 / 362880.0, -1.0 / 39916800.0, 1.0 / 6227020800.0
_T15, _T17 = -1.0 / 1307674368000.0, 1.0 / 355687428096000.0
_T19, _T21 = -1.0 / 121645100408832000.0, 1.0 / 51090942171709440000.0
_INV_PI = 0.31830988618379067154


@njit(cache=True, fastmath=FM, inline="always")
def _sin_or_cos(x, shift):
    """sin(x) (shift 0) or cos(x) (shift 1) without libm calls, so that loops vectorise.

    x = m*pi/2 + r with m even (sin) or odd (cos), |r| <= pi/2, by a three-part Cody-Waite
    reduction (exact products for |x| <= TRIG_REDUCE_MAX, callers check); then one odd
    polynomial: sin x = (-1)^k sin r, cos x = -(-1)^k sin r.
    """
    if shift == 0.0:
        k = math.floor(x * _INV_PI + 0.5)
        m = 2.0 * k
        sign = 1.0
    else:
        k = math.floor(x * _INV_PI)
        m = 2.0 * k + 1.0
        sign = -1.0
    r = ((x - m * _PIO2_1) - m * _PIO2_2) - m * _PIO2_3
    z = r * r
    p = _T19 + z * _T21
    p = _T17 + z * p
    p = _T15 + z * p
    p = _T13 + z * p
    p = _T11 + z * p
    p = _T9 + z * p
    p = _T7 + z * p
    p = _T5 + z * p
    p = _T3 + z * p
    v = r + r * z * p
    odd = k - 2.0 * math.floor(k * 0.5)
    return sign * v if odd < 0.5 else -sign * v


@njit(cache=True)
def _scalar_op(code, x, y):
    if code == ADD:
        return x + y
    if code == SUB:
        return x - y
    if code == MUL:
        return x * y
    if code == SQUARE:
        return x * x
    if code == CUBE:
        return x * x * x
    if code == SIN:
        return math.sin(x)
    if code == COS:
        return math.cos(x)
    if code == NEG:
        return -x
    if code == DIV:
        if abs(y) > DIV_EPS:
            return x / y
        return np.nan
    if code == SQRTABS:
        return math.sqrt(abs(x))
    if code == TAN:
        return math.tan(x)
    if code == ABS:
        return abs(x)
    if code == EXP:
        if x > 700.0:
            return np.inf
        return math.exp(x)
    if code == TANH:
        return math.tanh(x)
    return np.nan


@njit(cache=True, fastmath=FM)
def _vector_op(code, V, ra, na, rb, nb, ro, no):
    """V[ro, no] = op(V[ra, na], V[rb, nb]) elementwise (the second ignored for unary ops).

    Rows are addressed by index, not passed as views: a view costs an atomic reference-count
    increment and decrement, and at ~40 node evaluations per generation those were a tenth of
    the search time."""
    n = V.shape[2]
    if code == IDENT:
        for i in range(n):
            V[ro, no, i] = V[ra, na, i]
    elif code == ADD:
        for i in range(n):
            V[ro, no, i] = V[ra, na, i] + V[rb, nb, i]
    elif code == SUB:
        for i in range(n):
            V[ro, no, i] = V[ra, na, i] - V[rb, nb, i]
    elif code == MUL:
        for i in range(n):
            V[ro, no, i] = V[ra, na, i] * V[rb, nb, i]
    elif code == SQUARE:
        for i in range(n):
            V[ro, no, i] = V[ra, na, i] * V[ra, na, i]
    elif code == CUBE:
        for i in range(n):
            V[ro, no, i] = V[ra, na, i] * V[ra, na, i] * V[ra, na, i]
    elif code == SIN or code == COS:
        # one vectorised pass that also counts arguments beyond the exact reduction (NaN is not
        # counted, as before); only a row with such an argument is redone with libm
        shift = 0.0 if code == SIN else 1.0
        big = 0
        for i in range(n):
            x = V[ra, na, i]
            big += abs(x) > TRIG_REDUCE_MAX
            V[ro, no, i] = _sin_or_cos(x, shift)
        if big != 0:
            if code == SIN:
                for i in range(n):
                    V[ro, no, i] = math.sin(V[ra, na, i])
            else:
                for i in range(n):
                    V[ro, no, i] = math.cos(V[ra, na, i])
    elif code == NEG:
        for i in range(n):
            V[ro, no, i] = -V[ra, na, i]
    elif code == DIV:
        for i in range(n):
            d = V[rb, nb, i]
            V[ro, no, i] = V[ra, na, i] / d if abs(d) > DIV_EPS else np.nan
    elif code == SQRTABS:
        for i in range(n):
            V[ro, no, i] = math.sqrt(abs(V[ra, na, i]))
    elif code == TAN:
        for i in range(n):
            V[ro, no, i] = math.tan(V[ra, na, i])
    elif code == ABS:
        for i in range(n):
            V[ro, no, i] = abs(V[ra, na, i])
    elif code == EXP:
        for i in range(n):
            x = V[ra, na, i]
            V[ro, no, i] = math.exp(x) if x < 700.0 else np.inf
    elif code == TANH:
        for i in range(n):
            V[ro, no, i] = math.tanh(V[ra, na, i])
    else:
        for i in range(n):
            V[ro, no, i] = np.nan


@njit(cache=True)
def apply_op(code, xa, xb):
    """The compiled kernel of one operator on whole vectors (for tests against the numpy kernels)."""
    n = xa.shape[0]
    V = np.empty((1, 3, n))
    for i in range(n):
        V[0, 0, i] = xa[i]
        V[0, 1, i] = xb[i]
    _vector_op(code, V, 0, 0, 0, 1, 0, 2)
    out = np.empty(n)
    for i in range(n):
        out[i] = V[0, 2, i]
    return out


@njit(cache=True, fastmath=FM)
def _row_stats(V, r, node, nt, yc, syy):
    """(valid, constant, fit) of the output row ``V[r, node]``; fit = 1 - |corr(row, y)| on
    training columns.

    Invalid: any column (training or constraint) non-finite or above MAX_ABS in magnitude,
    counted in one integer pass (which vectorises, unlike a floating-point sum); the sums of
    the fit then run over the training columns only.
    """
    n = V.shape[2]
    bad = 0
    for i in range(n):
        bad += not (abs(V[r, node, i]) <= MAX_ABS)     # NaN compares false
    if bad != 0:
        return False, True, 1.0
    s0 = s1 = s2 = s3 = 0.0
    q0 = q1 = q2 = q3 = 0.0
    c0 = c1 = c2 = c3 = 0.0
    m = nt - nt % 4
    for i in range(0, m, 4):
        v0 = V[r, node, i]
        v1 = V[r, node, i + 1]
        v2 = V[r, node, i + 2]
        v3 = V[r, node, i + 3]
        s0 += v0
        s1 += v1
        s2 += v2
        s3 += v3
        q0 += v0 * v0
        q1 += v1 * v1
        q2 += v2 * v2
        q3 += v3 * v3
        c0 += v0 * yc[i]
        c1 += v1 * yc[i + 1]
        c2 += v2 * yc[i + 2]
        c3 += v3 * yc[i + 3]
    for i in range(m, nt):
        v = V[r, node, i]
        s0 += v
        q0 += v * v
        c0 += v * yc[i]
    sxx = (q0 + q1) + (q2 + q3)
    s = (s0 + s1) + (s2 + s3)
    sxy = (c0 + c1) + (c2 + c3)                # yc is centred: this is the centred sum
    mean = s / nt
    var = sxx - s * mean
    if var <= CONST_TOL * nt * (1.0 + mean * mean):
        return True, True, 1.0
    if syy <= 0.0:
        return True, False, 1.0
    c = abs(sxy) / math.sqrt(var * syy)
    if c > 1.0:
        c = 1.0
    return True, False, 1.0 - c


@njit(cache=True)
def _propagate(lo, hi, force, gen_id, mutated, stamp, dirty, d_valid, d_const, d_fit,
               op, a, b, cval, V, buf, valid, isconst, fit, lay, yc, syy):
    """Re-evaluate, in ascending order, the nodes n in [lo, hi) that were mutated in generation
    ``gen_id`` (``mutated[n] == gen_id``; every node when ``force`` is nonzero) or that use a node whose
    output changed in it; a re-evaluated node whose output comes out identical (e.g. invalid
    before and after) does not dirty its users. Terminal rows are never recomputed.

    Marks changed nodes with ``stamp[n] = gen_id`` and records every re-evaluated node and its
    previous valid/isconst/fit in ``dirty``/``d_valid``/``d_const``/``d_fit`` (the undo log).
    Returns (number re-evaluated, whether a feature slot's output changed).
    """
    nd = 0
    id_changed = False
    N = V.shape[2]
    nt = lay[L_NT]
    head = lay[L_HEAD]     # layout in locals: LLVM cannot tell that no store in the loop
    tail = lay[L_TAIL]     # writes into ``lay``, so it would reload it every iteration
    id0 = lay[L_ID]
    P = lay[L_P]
    for n in range(lo, hi):
        if n >= head and n < tail:
            continue
        # links of -1 (none) look up the sentinel stamp[P], which is never set; a stamp equal
        # to gen_id can only belong to a node at or above ``lo`` (set by this call)
        sa = a[n]
        sb = b[n]
        hit = ((force != 0) | (mutated[n] == gen_id) | (stamp[sa if sa >= 0 else P] == gen_id)
               | (stamp[sb if sb >= 0 else P] == gen_id))
        if not hit:
            continue
        dirty[nd] = n
        d_valid[nd] = valid[n]
        d_const[nd] = isconst[n]
        d_fit[nd] = fit[n]
        nd += 1
        # recompute node n into its spare row and flip buf[n] (written out here rather than as
        # an inlined function: numba's inlining re-binds every array argument with a reference
        # count increment and decrement, atomic operations that cost more per node than
        # evaluating a short row)
        nb = 1 - buf[n]
        code = op[n]
        vn = 1
        cn = 1
        fn = 1.0
        if n < head:                 # constants and head block: derived constants
            if code == CONST:
                val = cval[n]
            else:
                x = V[buf[sa], sa, 0]
                y = 0.0
                if sb >= 0:
                    y = V[buf[sb], sb, 0]
                val = _scalar_op(code, x, y)
                if not (abs(val) <= MAX_ABS):
                    val = cval[n]    # the node's proxy constant
            for t in range(N):
                V[nb, n, t] = val
        elif valid[sa] == 0 or (sb >= 0 and valid[sb] == 0):
            vn = 0
        elif code == IDENT:           # a feature slot just mirrors its successor
            ra = buf[sa]
            for t in range(N):
                V[nb, n, t] = V[ra, sa, t]
            vn = valid[sa]
            cn = isconst[sa]
            fn = fit[sa]
        else:
            if sb < 0:
                sb = sa
            _vector_op(code, V, buf[sa], sa, buf[sb], sb, nb, n)
            ok, cst, fn = _row_stats(V, nb, n, nt, yc, syy)
            vn = 1 if ok else 0
            cn = 1 if cst else 0
        buf[n] = nb
        valid[n] = vn
        isconst[n] = cn
        fit[n] = fn
        # did the output change? (validity, else the two rows; an invalid node's rows do not
        # matter). Written out here for the reason above.
        changed = vn != d_valid[nd - 1]
        if not changed and vn != 0:
            for t in range(N):
                if V[0, n, t] != V[1, n, t]:
                    changed = True
                    break
        if changed:
            stamp[n] = gen_id
            if n >= id0:
                id_changed = True
    return nd, id_changed


@njit(cache=True)
def _evaluate_one(n, op, a, b, cval, V, buf, valid, isconst, fit, lay, yc, syy, scratch):
    """Recompute node n alone (cold paths: initialisation, links set from outside);
    ``scratch`` from :func:`_undo_log`."""
    mutated, stamp, dirty, d_valid, d_const, d_fit = scratch
    _propagate(n, n + 1, np.int64(1), np.int64(0), mutated, stamp, dirty, d_valid, d_const,
               d_fit, op, a, b, cval, V, buf, valid, isconst, fit, lay, yc, syy)


@njit(cache=True)
def _undo_log(P):
    """The generation marks and undo log of :func:`_propagate` for a population of P nodes
    (``stamp`` has one more slot: the sentinel for "no link")."""
    return (np.zeros(P, dtype=np.int64), np.zeros(P + 1, dtype=np.int64),
            np.empty(P, dtype=np.int64), np.empty(P, dtype=np.uint8),
            np.empty(P, dtype=np.uint8), np.empty(P))


@njit(cache=True)
def _depths(a, b, lay, depth):
    t0 = lay[L_TAIL]
    for n in range(t0):
        depth[n] = 0
    for n in range(t0, lay[L_P]):
        d = depth[a[n]]
        if b[n] >= 0 and depth[b[n]] > d:
            d = depth[b[n]]
        depth[n] = d + 1


@njit(cache=True)
def _raise_bounds(m, s, a, b, lay, depth, ltr, stack):
    """After linking m -> s: raise depth bounds above m and levelsToRoot bounds below s."""
    d = depth[s] + 1
    if d > depth[m]:
        depth[m] = d
        for n in range(m + 1, lay[L_P]):
            dn = depth[a[n]]
            if b[n] >= 0 and depth[b[n]] > dn:
                dn = depth[b[n]]
            if dn + 1 > depth[n]:
                depth[n] = dn + 1
    t0 = lay[L_TAIL]
    if ltr[s] < ltr[m] + 1:
        ltr[s] = ltr[m] + 1
        top = 0
        stack[top] = s
        top += 1
        while top > 0:
            top -= 1
            n = stack[top]
            lp = ltr[n] + 1
            c = a[n]
            if c >= t0 and ltr[c] < lp:
                ltr[c] = lp
                stack[top] = c
                top += 1
            c = b[n]
            if c >= t0 and ltr[c] < lp:
                ltr[c] = lp
                stack[top] = c
                top += 1


@njit(cache=True)
def _terminal(lay):
    """A terminal: constant/head node or variable (incl. prior terminals), 50/50."""
    if lay[L_HEAD] > 0 and np.random.random() < 0.5:
        return np.random.randint(0, lay[L_HEAD])
    return np.random.randint(lay[L_HEAD], lay[L_TAIL])


@njit(cache=True)
def _pick_successor(m, ltr_m, depth, lay):
    """A new successor for tail/identity node m obeying depth(s) + levelsToRoot(m) < max depth."""
    t0 = lay[L_TAIL]
    hi = m if m < lay[L_ID] else lay[L_ID]
    if hi <= t0 or 1 + ltr_m >= lay[L_DEPTH] or np.random.random() < P_TERMINAL:
        return _terminal(lay)
    for _ in range(16):
        s = np.random.randint(t0, hi)
        if depth[s] + ltr_m < lay[L_DEPTH]:
            return s
    return _terminal(lay)


@njit(cache=True, fastmath=FM, inline="always")
def _dot(V, r, node, y, n):
    """Sum of V[r, node, t] * y[t] over the first n columns (four accumulators)."""
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for t in range(0, m, 4):
        s0 += V[r, node, t] * y[t]
        s1 += V[r, node, t + 1] * y[t + 1]
        s2 += V[r, node, t + 2] * y[t + 2]
        s3 += V[r, node, t + 3] * y[t + 3]
    for t in range(m, n):
        s0 += V[r, node, t] * y[t]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, fastmath=FM, inline="always")
def _dot_rows(V, r, node, r2, node2, n):
    """Sum of V[r, node, t] * V[r2, node2, t] over the first n columns (four accumulators)."""
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for t in range(0, m, 4):
        s0 += V[r, node, t] * V[r2, node2, t]
        s1 += V[r, node, t + 1] * V[r2, node2, t + 1]
        s2 += V[r, node, t + 2] * V[r2, node2, t + 2]
        s3 += V[r, node, t + 3] * V[r2, node2, t + 3]
    for t in range(m, n):
        s0 += V[r, node, t] * V[r2, node2, t]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, fastmath=FM, inline="always")
def _sum(x, n):
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for t in range(0, m, 4):
        s0 += x[t]
        s1 += x[t + 1]
        s2 += x[t + 2]
        s3 += x[t + 3]
    for t in range(m, n):
        s0 += x[t]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, fastmath=FM, inline="always")
def _sum_row(V, r, node, n):
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for t in range(0, m, 4):
        s0 += V[r, node, t]
        s1 += V[r, node, t + 1]
        s2 += V[r, node, t + 2]
        s3 += V[r, node, t + 3]
    for t in range(m, n):
        s0 += V[r, node, t]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, inline="always")
def _gidx(node, lay):
    """Row of a least-squares column in the Gram cache: 0 intercept, then priors, then slots."""
    if node < 0:
        return 0
    if node >= lay[L_ID]:
        return 1 + lay[L_NPRIOR] + node - lay[L_ID]
    return 1 + node - (lay[L_TAIL] - lay[L_NPRIOR])


@njit(cache=True)
def _gram_row(node, V, buf, valid, isconst, lay, y, gram, rhs):
    """Recompute the Gram-cache row and column of ``node`` (a prior or an identity node)
    against the intercept, the priors and every usable identity node; training columns only."""
    nt = lay[L_NT]
    g = _gidx(node, lay)
    r = buf[node]
    rhs[g] = _dot(V, r, node, y, nt)
    s = _sum_row(V, r, node, nt)
    gram[g, 0] = s
    gram[0, g] = s
    for p in range(lay[L_TAIL] - lay[L_NPRIOR], lay[L_TAIL]):
        h = _gidx(p, lay)
        v = _dot_rows(V, r, node, buf[p], p, nt)
        gram[g, h] = v
        gram[h, g] = v
    for m in range(lay[L_ID], lay[L_P]):
        if valid[m] == 0 or isconst[m] == 1:
            continue
        h = _gidx(m, lay)
        v = _dot_rows(V, r, node, buf[m], m, nt)
        gram[g, h] = v
        gram[h, g] = v


@njit(cache=True)
def _gram_full(V, buf, valid, isconst, lay, y, gram, rhs):
    nt = lay[L_NT]
    gram[0, 0] = nt
    rhs[0] = _sum(y, nt)
    for p in range(lay[L_TAIL] - lay[L_NPRIOR], lay[L_TAIL]):
        _gram_row(p, V, buf, valid, isconst, lay, y, gram, rhs)
    for m in range(lay[L_ID], lay[L_P]):
        if valid[m] == 1 and isconst[m] == 0:
            _gram_row(m, V, buf, valid, isconst, lay, y, gram, rhs)


@njit(cache=True)
def solve_fresh(op, V, buf, valid, isconst, fit, lay, y, ckind, cbound, beta, cols, obj, gram, rhs):
    """Rebuild the Gram cache and fit the model (after links were set from outside)."""
    _gram_full(V, buf, valid, isconst, lay, y, gram, rhs)
    wk, wkeep = _solve_work(cols.shape[0], V.shape[2])
    return _solve_model(op, V, buf, valid, isconst, fit, lay, y, ckind, cbound, beta, cols, obj,
                        gram, rhs, wk, wkeep)


@njit(cache=True)
def _solve_work(K, N):
    """Work buffers of :func:`_solve_model` for up to K columns and N samples (allocated once
    per chunk rather than once per generation)."""
    return np.empty(2 * K * K + 4 * K + N), np.empty(K, dtype=np.uint8)


@njit(cache=True, fastmath=FM)
def _solve_model(op, V, buf, valid, isconst, fit, lay, y, ckind, cbound, beta, cols, obj_out,
                 gram, rhs, wk, wkeep):
    """Least squares over [1 | priors | valid identity features]; fills beta/cols/obj_out.

    Returns False when no finite fit exists. Columns that are (numerically) linear combinations
    of earlier ones get coefficient 0: pivoted-out by a Cholesky factorisation of the
    column-normalised Gram matrix (so the intercept and the priors win over evolved features).
    Identity features with the same fitness as an earlier one are skipped (duplicate filter).
    The Gram matrix entries come from the cache ``gram``/``rhs`` (see :func:`_gram_row`);
    ``wk``/``wkeep`` are work buffers from :func:`_solve_work`.
    """
    P = lay[L_P]
    nt = lay[L_NT]
    N = V.shape[2]
    K = cols.shape[0]
    k = 0
    cols[k] = -1
    k += 1
    for p in range(lay[L_TAIL] - lay[L_NPRIOR], lay[L_TAIL]):
        cols[k] = p
        k += 1
    for n in range(lay[L_ID], P):
        if valid[n] == 0 or isconst[n] == 1:
            continue
        dup = False
        for j in range(1 + lay[L_NPRIOR], k):
            if fit[cols[j]] == fit[n]:
                dup = True
                break
        if dup or k >= K:
            continue
        cols[k] = n
        k += 1
    for j in range(k, K):
        cols[j] = -2
    kk = k * k
    G = wk[:kk].reshape((k, k))
    L = wk[kk:2 * kk].reshape((k, k))
    r = wk[2 * kk:2 * kk + k]
    d = wk[2 * kk + k:2 * kk + 2 * k]
    z = wk[2 * kk + 2 * k:2 * kk + 3 * k]
    x = wk[2 * kk + 3 * k:2 * kk + 4 * k]
    pred = wk[2 * kk + 4 * k:2 * kk + 4 * k + N]
    keep = wkeep[:k]
    for i in range(kk):
        wk[kk + i] = 0.0          # L
    for i in range(k):
        z[i] = 0.0
        x[i] = 0.0
        keep[i] = 1
    for i in range(k):
        gi = _gidx(cols[i], lay)
        r[i] = rhs[gi]
        for j in range(i + 1):
            v = gram[gi, _gidx(cols[j], lay)]
            G[i, j] = v
            G[j, i] = v
    # normalise and factorise with column dropping
    for i in range(k):
        if G[i, i] > 0.0 and G[i, i] < np.inf:
            d[i] = math.sqrt(G[i, i])
        else:
            d[i] = 1.0
            keep[i] = 0
    for j in range(k):
        if keep[j] == 0:
            continue
        s = G[j, j] / (d[j] * d[j])
        for p in range(j):
            if keep[p]:
                s -= L[j, p] * L[j, p]
        if not (s > PIVOT_TOL):
            keep[j] = 0
            continue
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, k):
            if keep[i] == 0:
                continue
            s2 = G[i, j] / (d[i] * d[j])
            for p in range(j):
                if keep[p]:
                    s2 -= L[i, p] * L[j, p]
            L[i, j] = s2 / L[j, j]
    for i in range(k):
        if keep[i] == 0:
            continue
        s = r[i] / d[i]
        for p in range(i):
            if keep[p]:
                s -= L[i, p] * z[p]
        z[i] = s / L[i, i]
    for i in range(k - 1, -1, -1):
        if keep[i] == 0:
            continue
        s = z[i]
        for p in range(i + 1, k):
            if keep[p]:
                s -= L[p, i] * x[p]
        x[i] = s / L[i, i]
    for i in range(K):
        beta[i] = 0.0
    for i in range(k):
        if keep[i]:
            beta[i] = x[i] / d[i]
            if not (abs(beta[i]) < np.inf):
                return False
    # predictions on all columns, then residuals (training) and violations (constraints)
    for t in range(N):
        pred[t] = beta[0]
    for i in range(1, k):
        if keep[i] == 0:
            continue
        ci = cols[i]
        ri = buf[ci]
        bi = beta[i]
        for t in range(N):
            pred[t] += bi * V[ri, ci, t]
    sse = 0.0
    for t in range(nt):
        e = y[t] - pred[t]
        sse += e * e
    sve = 0.0
    for t in range(nt, N):
        j = t - nt
        e = pred[t] - cbound[j]
        kd = ckind[j]
        if kd == 1:
            e = e if e > 0.0 else 0.0
        elif kd == 2:
            e = -e if e < 0.0 else 0.0
        sve += e * e
    ed = math.sqrt(sse / nt)
    ec = math.sqrt(sve / (N - nt)) if N > nt else 0.0
    if not (ed < np.inf and ec < np.inf):
        return False
    obj_out[O_ED] = ed
    obj_out[O_EC] = ec
    return True


@njit(cache=True, inline="always")
def _score(ed, ec, mode, weight):
    if mode == 0:
        return ed
    return (1.0 - weight) * ed + weight * ec


@njit(cache=True)
def _copy_links(a, b, a_out, b_out):
    """Element loops instead of slice assignment (whose shape check compiles string code)."""
    for i in range(a.shape[0]):
        a_out[i] = a[i]
        b_out[i] = b[i]


@njit(cache=True)
def _archive_insert(ed, ec, a, b, arch_obj, arch_a, arch_b, arch_n):
    """Keep (ed, ec) and its links if no archived model is at least as good in both."""
    n = arch_n[0]
    for i in range(n):
        if arch_obj[i, 0] <= ed and arch_obj[i, 1] <= ec:
            return
    j = 0
    for i in range(n):
        if ed <= arch_obj[i, 0] and ec <= arch_obj[i, 1]:
            continue   # dominated by the newcomer
        if j != i:
            arch_obj[j, 0] = arch_obj[i, 0]
            arch_obj[j, 1] = arch_obj[i, 1]
            _copy_links(arch_a[i], arch_b[i], arch_a[j], arch_b[j])
        j += 1
    n = j
    K = arch_obj.shape[0]
    if n >= K:
        # full: drop the most crowded interior point (by log-distance of its neighbours)
        order = np.empty(n, dtype=np.int64)    # by e_d; insertion sort (n <= 64, no argsort
        for i in range(n):                       # to compile)
            j = i
            while j > 0 and arch_obj[order[j - 1], 0] > arch_obj[i, 0]:
                order[j] = order[j - 1]
                j -= 1
            order[j] = i
        worst = -1
        gap = np.inf
        for q in range(1, n - 1):
            lo = order[q - 1]
            hi = order[q + 1]
            g = (math.log(arch_obj[hi, 0] + 1e-300) - math.log(arch_obj[lo, 0] + 1e-300)
                 + math.log(arch_obj[lo, 1] + 1e-300) - math.log(arch_obj[hi, 1] + 1e-300))
            if g < gap:
                gap = g
                worst = order[q]
        if worst < 0:
            return
        n -= 1
        if worst != n:
            arch_obj[worst, 0] = arch_obj[n, 0]
            arch_obj[worst, 1] = arch_obj[n, 1]
            _copy_links(arch_a[n], arch_b[n], arch_a[worst], arch_b[worst])
    arch_obj[n, 0] = ed
    arch_obj[n, 1] = ec
    _copy_links(a, b, arch_a[n], arch_b[n])
    arch_n[0] = n + 1


@njit(cache=True, nogil=True)
def init_population(seed, op, a, b, cval, V, buf, valid, isconst, fit, lay, y, yc, syy,
                    ckind, cbound, beta, cols, obj, gram, rhs):
    """Random links for head, tail and identity nodes; evaluate everything; fit the model."""
    np.random.seed(seed)
    P = lay[L_P]
    scratch = _undo_log(P)
    head0 = 0
    while head0 < lay[L_HEAD] and op[head0] == CONST:
        head0 += 1
    for n in range(lay[L_HEAD]):
        buf[n] = 0
        if n >= head0:
            a[n] = np.random.randint(0, n)
            b[n] = np.random.randint(0, n)
        _evaluate_one(n, op, a, b, cval, V, buf, valid, isconst, fit, lay, yc, syy, scratch)
    for n in range(lay[L_HEAD], lay[L_TAIL]):     # variables and prior terminals (rows preset)
        ok, cst, f = _row_stats(V, buf[n], n, lay[L_NT], yc, syy)
        valid[n] = 1 if ok else 0
        isconst[n] = 1 if cst else 0
        fit[n] = f
    depth = np.zeros(P, dtype=np.int64)
    for n in range(lay[L_TAIL], P):
        for attempt in range(20):
            a[n] = _pick_successor(n, np.int64(0), depth, lay)
            b[n] = -1
            if _is_binary(op[n]):
                b[n] = _pick_successor(n, np.int64(0), depth, lay)
            _evaluate_one(n, op, a, b, cval, V, buf, valid, isconst, fit, lay, yc, syy, scratch)
            if valid[n] == 1 and isconst[n] == 0:
                break
        d = depth[a[n]]
        if b[n] >= 0 and depth[b[n]] > d:
            d = depth[b[n]]
        depth[n] = d + 1
    ok = solve_fresh(op, V, buf, valid, isconst, fit, lay, y, ckind, cbound, beta, cols, obj,
                     gram, rhs)
    if not ok:
        obj[O_ED] = np.inf
        obj[O_EC] = np.inf
    return ok


@njit(cache=True)
def _is_binary(code):
    return code == ADD or code == SUB or code == MUL or code == DIV


@njit(cache=True, nogil=True)
def run_chunk(seed, n_gens, identity_only, weight, op, a, b, cval, V, buf, valid, isconst, fit,
              lay, y, yc, syy, ckind, cbound, beta, cols, obj, gram, rhs,
              arch_obj, arch_a, arch_b, arch_n, stats):
    """``n_gens`` generations of (1+1) local search on the population, in place.

    Each generation: k ~ U{1..10} mutations (identity relinks only when ``identity_only``),
    re-evaluation of the dirtied nodes in ascending index order, least-squares refit, and
    acceptance when the score is not worse (neutral moves accepted); otherwise undo.
    """
    np.random.seed(seed)
    P = lay[L_P]
    t0 = lay[L_TAIL]
    id0 = lay[L_ID]
    mode = lay[L_MODE]
    head0 = 0
    while head0 < lay[L_HEAD] and op[head0] == CONST:
        head0 += 1
    has_head = head0 < lay[L_HEAD]
    K = beta.shape[0]
    depth = np.zeros(P, dtype=np.int64)
    ltr = np.zeros(P, dtype=np.int64)
    stack = np.empty(P * (lay[L_DEPTH] + 2), dtype=np.int64)
    bp = np.empty(P)
    if identity_only:
        _depths(a, b, lay, depth)
    mutated, stamp, dirty, d_valid, d_const, d_fit = _undo_log(P)
    u_node = np.empty(MAX_MUTATIONS, dtype=np.int64)
    u_slot = np.empty(MAX_MUTATIONS, dtype=np.int64)
    u_old = np.empty(MAX_MUTATIONS, dtype=np.int64)
    nbeta = np.empty(K)
    ncols = np.empty(K, dtype=np.int64)
    nobj = np.zeros(3)
    KG = gram.shape[0]
    n_slots = P - id0
    g_node = np.empty(max(n_slots, 1), dtype=np.int64)
    g_row = np.empty((max(n_slots, 1), KG))
    g_rhs = np.empty(max(n_slots, 1))
    wk, wkeep = _solve_work(K, V.shape[2])
    depth0 = np.empty(P, dtype=np.int64)
    ltr0 = np.empty(P, dtype=np.int64)
    fresh = False
    obj[O_SCORE] = _score(obj[O_ED], obj[O_EC], mode, weight)
    for g in range(n_gens):
        gen_id = stats[S_GENS] + 1
        stats[S_GENS] = gen_id
        # bestPred (lowest fit among a node and everything that uses it) and levelsToRoot, in
        # one pass over the users (descending); depth in one ascending pass. Within the
        # generation both are then only raised (conservative bounds), recomputed next time:
        # after a rejected generation, links and fit are back as they were, so the values from
        # before its mutations (kept when the first bound was raised) are exact again.
        if not identity_only and not fresh:
            for n in range(P):
                bp[n] = fit[n]
                ltr[n] = 0
            for p in range(P - 1, t0 - 1, -1):
                lp = ltr[p] + 1
                s = a[p]
                if bp[p] < bp[s]:
                    bp[s] = bp[p]
                if ltr[s] < lp:
                    ltr[s] = lp
                s = b[p]
                if s >= 0:
                    if bp[p] < bp[s]:
                        bp[s] = bp[p]
                    if ltr[s] < lp:
                        ltr[s] = lp
            _depths(a, b, lay, depth)
        saved = False
        k = 1 if identity_only else np.random.randint(1, MAX_MUTATIONS + 1)
        nm = 0
        lowest = P
        for _ in range(k):
            if identity_only:
                m = np.random.randint(id0, P)
            elif has_head and np.random.random() < P_HEAD:
                m = np.random.randint(head0, lay[L_HEAD])
                for _t in range(TOURNAMENT - 1):
                    c = np.random.randint(head0, lay[L_HEAD])
                    if bp[c] < bp[m]:
                        m = c
            else:
                m = np.random.randint(t0, P)
                for _t in range(TOURNAMENT - 1):
                    c = np.random.randint(t0, P)
                    if bp[c] < bp[m]:
                        m = c
            slot = 0
            if b[m] >= 0 and np.random.random() < 0.5:
                slot = 1
            if m < lay[L_HEAD]:
                s = np.random.randint(0, m)
            elif identity_only:
                s = _pick_successor(m, np.int64(0), depth, lay)   # identity nodes have no users
            else:
                s = _pick_successor(m, ltr[m], depth, lay)
                if s >= t0:
                    if not saved:
                        for i in range(P):
                            depth0[i] = depth[i]
                            ltr0[i] = ltr[i]
                        saved = True
                    _raise_bounds(m, s, a, b, lay, depth, ltr, stack)
            u_node[nm] = m
            u_slot[nm] = slot
            if slot == 0:
                u_old[nm] = a[m]
                a[m] = s
            else:
                u_old[nm] = b[m]
                b[m] = s
            nm += 1
            mutated[m] = gen_id
            if m < lowest:
                lowest = m
        # re-evaluate the mutated nodes and every node above a changed one, ascending
        nd, id_changed = _propagate(lowest, P, np.int64(0), gen_id, mutated, stamp, dirty, d_valid,
                                    d_const, d_fit, op, a, b, cval, V, buf, valid, isconst, fit,
                                    lay, yc, syy)
        stats[S_EVALS] += nd
        accept = False
        ng = 0
        if not id_changed:
            accept = True          # the model is the same: a neutral move
        else:
            # refresh the Gram-cache rows of the feature slots that changed (undo log kept)
            for n in range(id0, P):
                if stamp[n] == gen_id and valid[n] == 1 and isconst[n] == 0:
                    g = _gidx(n, lay)
                    g_node[ng] = g
                    g_rhs[ng] = rhs[g]
                    for j in range(KG):
                        g_row[ng, j] = gram[g, j]
                    ng += 1
                    _gram_row(n, V, buf, valid, isconst, lay, y, gram, rhs)
            stats[S_SOLVES] += 1
            ok = _solve_model(op, V, buf, valid, isconst, fit, lay, y, ckind, cbound, nbeta, ncols,
                              nobj, gram, rhs, wk, wkeep)
            if ok:
                sc = _score(nobj[O_ED], nobj[O_EC], mode, weight)
                if mode == 1:
                    _archive_insert(nobj[O_ED], nobj[O_EC], a, b, arch_obj, arch_a, arch_b, arch_n)
                if sc <= obj[O_SCORE]:
                    accept = True
                    obj[O_ED] = nobj[O_ED]
                    obj[O_EC] = nobj[O_EC]
                    obj[O_SCORE] = sc
                    for i in range(K):
                        beta[i] = nbeta[i]
                        cols[i] = ncols[i]
            else:
                stats[S_FAILED] += 1
        if accept:
            stats[S_ACCEPT] += 1
            fresh = False
        else:
            if saved:
                for i in range(P):
                    depth[i] = depth0[i]
                    ltr[i] = ltr0[i]
            fresh = True
            for i in range(ng - 1, -1, -1):
                g = g_node[i]
                rhs[g] = g_rhs[i]
                for j in range(KG):
                    gram[g, j] = g_row[i, j]
                    gram[j, g] = g_row[i, j]
            for i in range(nm - 1, -1, -1):
                if u_slot[i] == 0:
                    a[u_node[i]] = u_old[i]
                else:
                    b[u_node[i]] = u_old[i]
            for i in range(nd):
                n = dirty[i]
                buf[n] = 1 - buf[n]
                valid[n] = d_valid[i]
                isconst[n] = d_const[i]
                fit[n] = d_fit[i]
    return stats[S_GENS]


@njit(cache=True)
def evaluate_all(op, a, b, cval, V, buf, valid, isconst, fit, lay, yc, syy):
    """Recompute every non-terminal node in ascending order (after links were set from outside)."""
    for n in range(lay[L_HEAD], lay[L_TAIL]):     # variables and prior terminals (rows preset)
        ok, cst, f = _row_stats(V, buf[n], n, lay[L_NT], yc, syy)
        valid[n] = 1 if ok else 0
        isconst[n] = 1 if cst else 0
        fit[n] = f
    mutated, stamp, dirty, d_valid, d_const, d_fit = _undo_log(lay[L_P])
    _propagate(np.int64(0), lay[L_P], np.int64(1), np.int64(0), mutated, stamp, dirty, d_valid,
               d_const, d_fit, op, a, b, cval, V, buf, valid, isconst, fit, lay, yc, syy)


# ------------------------------------------------------------------------------------------------
# the compiled-code cache


@njit(cache=True)
def _target_probe():
    """Nothing: its first call sets up numba's CPU target (see :func:`set_up_target`)."""
    return 0


#: The kernels Python calls (everything else is compiled into them).
ENTRY_KERNELS = ("init_population", "run_chunk", "solve_fresh", "evaluate_all", "_archive_insert",
                 "_target_probe")

_BLAS_PROBE = "scipy.linalg.cython_blas"


def set_up_target(skip_blas_probe: bool = False) -> None:
    """Set up numba's CPU target now, as the first kernel call would: numba imports its
    implementations of Python and numpy (about a third of a ``droneid fit`` start-up).

    ``skip_blas_probe``: numba's set-up imports scipy.linalg (~0.25 s, half of the set-up) only
    to see whether BLAS is there for the inner products of ``np.correlate``/``np.convolve``;
    no SNGP kernel uses them. With True, for a process that runs only the SNGP kernels (``droneid
    fit``), the probe finds no BLAS, so in this process numba computes those two with its own
    loop; ``np.dot`` and ``np.linalg`` still import scipy when first compiled. The SNGP kernels
    are the same compiled code either way. A numba whose set-up needs scipy's BLAS outright is
    set up the ordinary way. The cached kernels are then read as :func:`use_cached_code` says."""
    use_cached_code()
    if not skip_blas_probe or "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        _target_probe()
        return
    sys.modules[_BLAS_PROBE] = None     # `import scipy.linalg.cython_blas` raises ImportError
    try:
        _target_probe()
    except Exception:   # noqa: BLE001 - a numba that needs BLAS here: set up as usual below
        pass
    finally:
        if sys.modules.get(_BLAS_PROBE, False) is None:
            del sys.modules[_BLAS_PROBE]
    _target_probe()


def kernels_ready() -> bool:
    """Whether every entry kernel is compiled in this process or cached on disk for this source.

    Reads numba's cache index (an internal of numba; on any surprise the answer is False, which
    only makes the caller say "compiling" when it might merely be loading)."""
    for name in ENTRY_KERNELS:
        dispatcher = globals()[name]
        if dispatcher.signatures:
            continue
        try:
            if not dispatcher._cache._cache_file._load_index():
                return False
        except Exception:   # noqa: BLE001 - a numba internal: unknown means "not ready"
            return False
    return True


# ------------------------------------------------------------------------------------------------
# reading the cached code without numba's compiler set-up

#: whether :func:`use_cached_code` installs the light loading (``load_from_cache_lightly(False)``
#: turns it off for this process)
_light_wanted = True


def use_cached_code() -> None:
    """Called before the first kernel call of a fit (and by :func:`set_up_target`): the entry
    kernels read their cached machine code lightly (:func:`load_from_cache_lightly`) unless this
    process turned that off. Idempotent and cheap; nothing happens when the module is imported."""
    if _light_wanted:
        load_from_cache_lightly()


def load_from_cache_lightly(on: bool = True) -> bool:
    """Have the entry kernels read their cached machine code without numba's target refresh;
    numba's own loading and compiling remain the fallback. Returns whether it is in place (False:
    this numba lacks the internals it relies on, or ``on`` is False). Idempotent.

    Why: before it reads a cached kernel, numba "refreshes" its CPU target, importing and
    registering its typing and lowering implementations of all of Python and numpy (numba.np.*,
    numba.cpython.*, typed containers, ...: 0.15-0.35 s, a fifth of a ``droneid fit`` process).
    A kernel read from the cache is machine code: it needs numba's runtime (NRT) set up and
    nothing of the compiler. So the entry kernels' caches read their code after setting up the
    runtime only; whenever that finds no usable entry (no cache yet, a changed source, another
    signature) or fails in any way, numba's own path runs, with its full set-up, and compiles as
    always. The code that runs is the cached code either way: results are bit for bit the same.

    ``on=False`` gives numba its own loading back for the rest of the process (kernels already
    loaded stay loaded) and keeps :func:`use_cached_code` from installing the light one again."""
    global _light_wanted
    _light_wanted = bool(on)
    if not on:
        for name in ENTRY_KERNELS:
            vars(globals()[name]._cache).pop("load_overload", None)
        return False
    try:
        from numba.core.runtime import rtsys
        caches = [globals()[name]._cache for name in ENTRY_KERNELS]
        for cache in caches:    # numba's cache internals this relies on
            cache._load_overload, cache._guard_against_spurious_io_errors, cache.load_overload
        rtsys.initialize    # noqa: B018
    except Exception:   # noqa: BLE001 - another numba: its own loading, as always
        return False
    for cache in caches:
        if "load_overload" not in vars(cache):
            cache.load_overload = _light_loader(cache, rtsys)
    return True


def _light_loader(cache, rtsys):
    """``cache.load_overload`` that reads the code after setting up numba's runtime only; on no
    entry or any failure, the cache's own ``load_overload`` (full target set-up)."""
    full = cache.load_overload

    def load_overload(sig, target_context):
        cres = None
        try:
            rtsys.initialize(target_context)    # the loaded code calls into the runtime
            with cache._guard_against_spurious_io_errors():
                cres = cache._load_overload(sig, target_context)
        except Exception as exc:    # noqa: BLE001 - numba's own path below decides
            _log.debug("light kernel loading failed (%s); numba's own loading follows", exc)
            cres = None
        return cres if cres is not None else full(sig, target_context)

    return load_overload
