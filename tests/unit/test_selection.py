"""The one selection rule: qualified models first by e_d, the rest by e_c, NaN last."""
import math

from hypothesis import given, strategies as st

from droneid.identify.pipeline import RunRecord, select_best
from droneid.sngp.selection import best_index, nan_last, rank

err = st.one_of(st.floats(0, 1e3), st.just(math.nan))


def test_a_qualified_model_beats_any_unqualified_one():
    assert rank(100.0, 9.0, True) < rank(0.001, 0.0, False)


def test_nan_ranks_last():
    assert nan_last(math.nan) == math.inf and nan_last(None) == math.inf
    assert rank(1e9, 0, True) < rank(math.nan, 0, True)


@given(st.lists(st.tuples(err, err, st.booleans()), min_size=1, max_size=8))
def test_best_index_is_the_minimum_of_the_rule(rows):
    i = best_index(rows, lambda r: r[0], lambda r: r[1], lambda r: r[2])
    if any(q for _, _, q in rows):
        assert rows[i][2]  # a qualified one whenever there is one
        assert nan_last(rows[i][0]) == min(nan_last(r[0]) for r in rows if r[2])
    else:
        assert nan_last(rows[i][1]) == min(nan_last(r[1]) for r in rows)


def test_identify_picks_runs_by_training_error_with_the_same_rule():
    runs = [RunRecord(rmse_train=0.1, constraint_rmse_train=0.9, qualified=False),
            RunRecord(rmse_train=0.5, constraint_rmse_train=0.01, qualified=True),
            None,
            RunRecord(rmse_train=0.3, constraint_rmse_train=0.02, qualified=True, rmse_test=0.0)]
    assert select_best(runs) == 3
    assert select_best([None]) is None
    assert select_best([runs[0], RunRecord(rmse_train=0.05, constraint_rmse_train=2.0, qualified=False)]) == 0
