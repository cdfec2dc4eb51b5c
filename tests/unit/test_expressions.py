import numpy as np
import pytest
import sympy as sp

from droneid.core.constraint_samples import ConstraintSamples, EQ, GE, LE, constraint_rmse, violations
from droneid.errors import ConfigError
from droneid.core.expressions import compile_expression, parse_expression, symbol


def test_parse_tilt_drag_term():
    e = parse_expression("g*cos(yaw)*tan(pitch)/cos(roll) - k_D*vx", ["vx", "roll", "pitch", "yaw"],
                         {"g": 9.81, "k_D": 0.28})
    f = compile_expression(e, ["vx", "roll", "pitch", "yaw"])
    v = f({"vx": np.array([1.0]), "roll": np.array([0.0]), "pitch": np.array([0.1]), "yaw": np.array([0.0])})
    assert v[0] == pytest.approx(9.81 * np.tan(0.1) - 0.28)


@pytest.mark.parametrize("text", [
    "__import__('os').system('true')", "vx.__class__", "[vx]", "lambda: 1", "open('f')",
    "vx if vx else 1", "eval('1')", "vx[0]", "f(vx)", "sin(x=vx)",
])
def test_anything_else_is_rejected(text):
    with pytest.raises(ConfigError):
        parse_expression(text, ["vx"])


def test_unknown_name_suggests():
    with pytest.raises(ConfigError, match="did you mean 'pitch'"):
        parse_expression("sin(ptich)", ["pitch"])


def test_caret_is_power_and_constants_broadcast():
    e = parse_expression("vx^2 + pi", ["vx"])
    assert sp.simplify(e - (symbol("vx") ** 2 + sp.pi)) == 0
    c = compile_expression(parse_expression("2", ["vx"]), ["vx"])
    assert c({"vx": np.zeros(3)}).shape == (3,)


def test_constraint_violations():
    cs = ConstraintSamples(np.zeros((3, 1)), [EQ, LE, GE], [0.0, 1.0, 1.0], [0, 1, 2], ("vx",))
    np.testing.assert_allclose(violations(np.array([0.5, 2.0, 2.0]), cs), [0.5, 1.0, 0.0])
    assert constraint_rmse(np.array([0.0, 0.0, 0.0]), cs) == pytest.approx(np.sqrt(1 / 3))
