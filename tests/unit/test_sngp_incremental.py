"""The search re-evaluates only the nodes a generation can have changed (``_propagate``) and undoes
rejected generations; after any number of generations the population must equal one evaluated
from scratch (``evaluate_all``) on its final links: every current row, validity, constancy, fit."""
import numpy as np
import pytest

from droneid.sngp import kernels as K
from droneid.sngp import population as popmod
from droneid.sngp.operators import DEFAULT_FUNCTIONS
from droneid.sngp.population import Problem
from droneid.sngp.search import ARCHIVE_SIZE


def _problem(n=120, constrained=False, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, (n, 3))
    y = np.sin(X[:, 0]) * X[:, 1] - 0.3 * X[:, 2] * np.abs(X[:, 2]) + 0.05 * rng.normal(size=n)
    m = 8 if constrained else 0
    cols = np.vstack([X, rng.uniform(-2, 2, (m, 3))]).T        # terminal rows over all columns
    yc = y - y.mean()
    ckind = np.zeros(m, dtype=np.int64)
    return Problem(y=y, yc=yc, syy=float(yc @ yc), ckind=ckind, cbound=np.zeros(m), terminals=cols), n + m


@pytest.mark.parametrize("constrained, identity_only", [(False, False), (True, False), (False, True)])
def test_incremental_state_equals_a_fresh_evaluation(constrained, identity_only):
    problem, n_columns = _problem(constrained=constrained)
    rng = np.random.default_rng(1)
    pop = popmod.build_population(tuple(DEFAULT_FUNCTIONS), 120, 3, 0, 5, 6, problem.y.size, n_columns,
                                  constrained, rng)
    popmod.load_terminals(pop, problem)
    popmod.init(pop, problem, 7)
    P = int(pop.lay[K.L_P])
    arch = (np.zeros((ARCHIVE_SIZE, 2)), np.zeros((ARCHIVE_SIZE, P), dtype=np.int64),
            np.zeros((ARCHIVE_SIZE, P), dtype=np.int64), np.zeros(1, dtype=np.int64))
    stats = np.zeros(K.N_STATS, dtype=np.int64)
    popmod.run(pop, problem, 11, 400, identity_only, 1.0, arch, stats)
    assert stats[K.S_GENS] == 400 and stats[K.S_EVALS] > 0
    assert 0 < stats[K.S_ACCEPT] < 400           # both accepted and undone generations happened
    fresh = pop.copy()
    popmod.evaluate_all(fresh, problem)
    for n in range(P):
        assert fresh.valid[n] == pop.valid[n], n
        if pop.valid[n]:
            np.testing.assert_array_equal(fresh.current(n), pop.current(n), err_msg=f"node {n}")
            assert fresh.isconst[n] == pop.isconst[n] and fresh.fit[n] == pop.fit[n], n
