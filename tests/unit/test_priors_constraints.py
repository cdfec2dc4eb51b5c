import math

import numpy as np
import pytest

from droneid.core.constraint_samples import EQ, GE, LE, constraint_rmse
from droneid.errors import ConfigError, MissingSignalError
from priors.registry import get_constraints, get_prior
from priors.constraints import (CONSTRAINT_SETS, Constraint, ConstraintSet,
                                load_constraints)

A = math.pi / 15


@pytest.mark.parametrize("target", ["vx_dot", "vy_dot"])
def test_tilt_drag_satisfies_the_paper_constraints_exactly(target):
    prior = get_prior("tilt-drag")
    cs = get_constraints("paper", target)
    assert len(cs) == 4
    for n_feat in (1, 3):
        for seed in (0, 1):
            s = cs.sample(prior.inputs(target), 50, seed=seed)
            cols = {n: s.X[:, i] for i, n in enumerate(s.input_names)}
            pred = prior.evaluate(cols, target, n_feat).sum(axis=1)
            assert constraint_rmse(pred, s) < 1e-12
    # and a model that ignores the yaw geometry violates them
    s = cs.sample(prior.inputs(target), 50, seed=0)
    pitch = s.X[:, s.input_names.index("pitch")]
    roll = s.X[:, s.input_names.index("roll")]
    assert constraint_rmse(9.81 * np.tan(pitch) + 9.81 * np.tan(roll), s) > 0.1


def test_paper_domains():
    cs = get_constraints("paper", "vx_dot")
    assert cs.inputs == ("vx", "pitch", "roll", "yaw")
    d = [dict(c.domain) for c in cs.constraints]
    assert d[0] == {"vx": 0.0, "pitch": 0.0, "roll": (-A, A), "yaw": 0.0}
    assert d[1] == {"vx": 0.0, "pitch": 0.0, "roll": (-A, A), "yaw": math.pi}
    assert d[2] == {"vx": 0.0, "pitch": (-A, A), "roll": 0.0, "yaw": math.pi / 2}
    assert d[3] == {"vx": 0.0, "pitch": (-A, A), "roll": 0.0, "yaw": -math.pi / 2}
    dy = [dict(c.domain) for c in get_constraints("paper", "vy_dot").constraints]
    assert dy[0] == {"vy": 0.0, "pitch": (-A, A), "roll": 0.0, "yaw": 0.0}
    assert dy[2] == {"vy": 0.0, "pitch": 0.0, "roll": (-A, A), "yaw": math.pi / 2}
    assert all(c.relation == "eq" and c.value == 0.0 for c in cs.constraints)


def test_sampling_shapes_order_seeds_and_defaults():
    cs = get_constraints("paper", "vx_dot")
    inputs = ("yaw", "throttle", "vx", "roll", "pitch")
    s = cs.sample(inputs, 50, seed=3)
    assert s.X.shape == (200, 5) and s.input_names == inputs
    assert np.all(s.kind == EQ) and np.all(s.bound == 0.0)
    assert np.array_equal(np.bincount(s.group), [50] * 4)
    assert np.all(s.X[:, 1] == 0.0)  # not named by any constraint: 0
    roll = s.X[s.group == 0, 3]
    assert roll.min() >= -A and roll.max() <= A and roll.std() > 0.05
    assert np.array_equal(cs.sample(inputs, 50, seed=3).X, s.X)
    train, test = cs.train_test(inputs, 50, seed=3)
    assert len(train) == len(test) == 200 and not np.array_equal(train.X, test.X)
    with_default = ConstraintSet("vx_dot", cs.constraints, defaults={"throttle": 0.5})
    assert np.all(with_default.sample(inputs, 5).X[:, 1] == 0.5)


def test_missing_input_names_the_constraint():
    cs = get_constraints("paper", "vx_dot")
    with pytest.raises(MissingSignalError, match=r"'yaw'.*constraint 'vx_dot = 0 at vx=0, pitch=0, yaw=0'"):
        cs.sample(("vx", "pitch", "roll"))


@pytest.mark.parametrize("domain, match", [
    ({"roll": (0.2, -0.2)}, "empty: lo 0.2 > hi -0.2"),
    ({"roll": (float("nan"), 0.2)}, "finite"),
    ({"roll": float("nan")}, "finite"),
    ({}, "empty domain"),
    ({"roll": (1, 2, 3)}, "value or"),
])
def test_degenerate_domains_name_the_constraint(domain, match):
    with pytest.raises(ConfigError, match=match) as exc:
        Constraint("level", domain, "eq", 0.0, "vx_dot")
    assert "constraint 'level'" in str(exc.value)


def test_turtlebot_constraints_hold_for_the_unicycle():
    prior = get_prior("unicycle")
    for target in ("x_dot", "y_dot"):
        cs = get_constraints("paper", target)
        assert len(cs) == 3
        s = cs.sample(prior.inputs(target), 50, seed=0)
        cols = {n: s.X[:, i] for i, n in enumerate(s.input_names)}
        assert constraint_rmse(prior.evaluate(cols, target).sum(axis=1), s) < 1e-12
    assert get_constraints("paper", "vx_dot", prior="tilt-drag").name == "paper"
    with pytest.raises(ConfigError, match="did you mean 'paper'"):
        get_constraints("papr", "vx_dot")
    with pytest.raises(ConfigError, match="did you mean 'unicycle'"):
        get_constraints("paper", "x_dot", prior="unicycl")
    assert set(CONSTRAINT_SETS) == {"paper"}


TOML = '''
name = "mine"
target = "vx_dot"
[defaults]
throttle = 0.5

[[constraint]]
name = "level, at rest"
domain = { vx = 0, pitch = 0, roll = ["-pi/15", "pi/15"], yaw = 0 }

[[constraint]]
name = "drag slows"
relation = "le"
value = 0.0
domain = { vx = [0.5, 3.0], pitch = 0, roll = 0, yaw = [-3.14, 3.14] }

[[constraint]]
name = "vy bound"
target = "vy_dot"
relation = ">="
value = -20
domain = { vy = [-5, 5] }
'''


def test_user_constraints_from_toml(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text(TOML)
    cs = load_constraints(p, target="vx_dot")
    assert cs.name == "mine" and len(cs) == 2
    assert cs.constraints[0].domain["roll"] == pytest.approx((-A, A))
    s = cs.sample(("vx", "pitch", "roll", "yaw", "throttle"), 10, seed=0)
    assert list(np.unique(s.kind)) == [EQ, LE]
    assert np.all(s.X[:, 4] == 0.5)
    vy = load_constraints(p, target="vy_dot")
    assert vy.constraints[0].relation == "ge" and vy.sample(("vy",), 4).kind[0] == GE
    with pytest.raises(ConfigError, match="several targets"):
        load_constraints(p)
    with pytest.raises(ConfigError, match="no constraints for 'vz_dot'"):
        load_constraints(p, target="vz_dot")


@pytest.mark.parametrize("body, match", [
    ('target = "vx_dot"\n[[constraint]]\nname = "bad"\ndomain = { roll = [0.3, 0.1] }', "constraint 'bad'.*empty"),
    ('target = "vx_dot"\n[[constraint]]\nname = "bad"\ndomain = { roll = "__import__(\'os\')" }', "constraint 'bad'.*not allowed"),
    ('target = "vx_dot"\n[[constraint]]\nname = "bad"\nrelation = "lt"\ndomain = { roll = 0 }', "constraint 'bad'.*relation"),
    ('target = "vx_dot"\n[[constraint]]\nname = "bad"\ndomain = { roll = 0 }\nweight = 2', "constraint 'bad'.*unknown key 'weight'"),
    ('[[constraint]]\nname = "bad"\ndomain = { roll = 0 }', "constraint 'bad'.*no target"),
    ('target = "vx_dot"\n', "no \\[\\[constraint\\]\\]"),
    ('target = "vx_dot"\n[[constraint]\n', "not valid TOML"),
])
def test_bad_constraint_files(tmp_path, body, match):
    p = tmp_path / "bad.toml"
    p.write_text(body)
    with pytest.raises(ConfigError, match=match) as exc:
        load_constraints(p)
    assert "bad.toml" in str(exc.value)
