"""The expression guard: hostile but syntactically valid expressions are rejected fast with a
ConfigError naming the expression; compile_expression never raises anything but DroneIdError."""
import time

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings, strategies as st

from droneid.errors import ConfigError, DroneIdError, MissingSignalError
from droneid.core.expressions import compile_expression, parse_expression, safe_format, symbol


@pytest.mark.parametrize("text, part", [
    ("9**9**9*vx", "9**9**9"),                  # power tower: sympy would compute it exactly
    ("9.0**9.0**9.0*vx", "9.0**9.0**9.0"),
    ("10**400*vx", "10**400"),                  # OverflowError in lambdify before
    ("2**10000000*vx", "2**10000000"),          # int digit limit before
    ("((10**100)**3)**2*vx", "((10**100)**3)**2"),
    ("vx**(10**100)", "vx**(10**100)"),         # exponent bound on a signal's power
    ("(vx+1)**100000", "(vx+1)**100000"),
    ("vx/0", "vx/0"),                           # KeyError 'ComplexInfinity' before
    ("log(0)*vx", "log(0)"),
    ("0**-1*vx", "0**-1"),
    ("vx*(1/0.0)", "1/0.0"),
    ("1e400*vx", "1e400"),                      # a float literal that is inf
    ("exp(1000)*vx", "exp(1000)"),
    ("exp(exp(exp(9)))*vx", "exp(exp(9))"),
    ("sqrt(-1)*vx", "sqrt(-1)"),                # complex constants: numpy would drop the imaginary part
    ("acos(2)*vx", "acos(2)"),
    ("min()*vx", "min()"),                      # Min() is +oo
    ("1" * 400 + "*vx", "1111"),                # integer literal beyond float64
    ("max(" + ",".join(f"vx*{i}" for i in range(1, 20)) + ")", "max("),
])
def test_hostile_expressions_are_rejected_naming_the_part(text, part):
    t0 = time.perf_counter()
    with pytest.raises(ConfigError) as info:
        parse_expression(text, ["vx"], what="--prior")
    assert time.perf_counter() - t0 < 2.0
    msg = str(info.value)
    assert msg.startswith("--prior: ") and part in msg


def test_deep_nesting_is_rejected_not_a_recursion_error():
    with pytest.raises(ConfigError, match="nested more than"):
        parse_expression("-" * 1990 + "vx", ["vx"])
    with pytest.raises(ConfigError, match="nested more than"):
        parse_expression("sin(-" * 120 + "vx" + ")" * 120, ["vx"])


def test_long_flat_sums_are_not_nesting():
    assert parse_expression("+".join(["vx"] * 600), ["vx"]) == 600 * symbol("vx")
    e = parse_expression("-".join(["1.5*vx"] * 250) + "*2/3", ["vx"])  # 1.5 - 248 * 1.5 - 1
    assert compile_expression(e, ["vx"])({"vx": np.array([1.0])})[0] == pytest.approx(-371.5)
    t0 = time.perf_counter()  # distinct terms sympy cannot merge
    text = "+".join(f"x{i}*y{i}" for i in range(250))[:2000]
    text = text[:text.rindex("+")]
    e = parse_expression(text, [f"{c}{i}" for i in range(250) for c in "xy"])
    assert len(e.args) == text.count("+") + 1 > 150
    assert time.perf_counter() - t0 < 5.0
    with pytest.raises(ConfigError):  # Python's own parser limit (too many parentheses)
        parse_expression("sin(" * 300 + "vx" + ")" * 300, ["vx"])


def test_nested_max_cannot_grow_past_the_argument_bound():
    inner = "max(" + ",".join(f"vx*{i}" for i in range(1, 7)) + ")"
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match="arguments"):
        parse_expression("max(" + ",".join([inner] * 6) + ")", ["vx"])
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize("text", ["vx**2", "vx**-3", "vx**0.5", "10**-300*vx", "2**0.5*vx", "1e308*vx",
                                  "exp(700)*vx", "(1/7)**300*vx", "vx**729", "max(vx, 1, 2)",
                                  "-(-(-vx))", "sin(sin(sin(vx)))", "9**9*vx"])
def test_ordinary_expressions_still_parse(text):
    e = parse_expression(text, ["vx"])
    v = compile_expression(e, ["vx"])({"vx": np.array([0.5, 1.0])})
    assert v.shape == (2,)


def test_physics_prior_unchanged():
    e = parse_expression("g*cos(yaw)*tan(pitch)/cos(roll) - k_D*vx", ["vx", "roll", "pitch", "yaw"],
                         {"g": 9.81, "k_D": 0.28})
    assert e.free_symbols == {symbol("vx"), symbol("roll"), symbol("pitch"), symbol("yaw")}


def test_a_parameter_product_beyond_float64_is_rejected():
    with pytest.raises(ConfigError, match="float64"):
        parse_expression("k*k*vx", ["vx"], {"k": 1e300})


def test_priors_toml_rejects_division_by_zero(tmp_path):
    from priors.user import load_priors
    p = tmp_path / "p.toml"
    p.write_text('[prior.bad]\ntarget = "vx_dot"\nfeatures = ["vx/0"]\n')
    with pytest.raises(ConfigError, match=r"p\.toml: prior 'bad'.*'vx/0' is infinite"):
        load_priors(p)


def test_constraints_toml_rejects_power_tower(tmp_path):
    from priors.constraints import load_constraints
    p = tmp_path / "c.toml"
    p.write_text('[[constraint]]\ntarget = "vx_dot"\nrelation = "eq"\nvalue = "9**9**9"\n'
                 '[constraint.domain]\nvx = 0\n')
    t0 = time.perf_counter()
    with pytest.raises(ConfigError):
        load_constraints(p, target="vx_dot")
    assert time.perf_counter() - t0 < 2.0


# -- compile_expression: only DroneIdError escapes ---------------------------------------------

@pytest.mark.parametrize("expr", [
    sp.zoo * symbol("vx"), sp.nan * symbol("vx"), sp.oo + symbol("vx"),
    sp.Integer(10) ** 400 * symbol("vx"), sp.Integer(2) ** 100000 * symbol("vx"),
    sp.I * symbol("vx"), sp.sqrt(symbol("vx")),
])
def test_compile_turns_non_finite_constants_into_inf_or_nan(expr):
    v = compile_expression(expr, ["vx"])({"vx": np.array([-1.0, 2.0])})
    assert v.dtype == np.float64 and v.shape == (2,)
    assert not np.isfinite(v).all()


def test_compile_rejects_non_sympy_and_missing_columns():
    with pytest.raises(ConfigError, match="sympy expression"):
        compile_expression("vx+1", ["vx"])
    with pytest.raises(MissingSignalError):
        compile_expression(symbol("vx") + symbol("vy"), ["vx"])
    f = compile_expression(symbol("vx") + 1, ["vx"])
    with pytest.raises(MissingSignalError):
        f({"vy": np.zeros(2)})


# -- fuzz: hostile token soup, seeded and time-bounded ------------------------------------------

_ATOMS = ["vx", "vy", "0", "1", "2", "9", "10", "0.0", "1e308", "1e400", "1e-400", "400", "10000000",
          "pi", "e", "nan", "inf", "k", "'s'", "True", "None", "x.y", "[vx]", "()"]
_OPS = ["+", "-", "*", "/", "**", "^", "%", "//", "<<", "&", " if vx else ", ",", "==", "."]
_FUNCS = ["sin(", "log(", "exp(", "sqrt(", "acos(", "max(", "min(", "atan2(", "abs(", "sign(",
          "tan(", "open(", "__import__(", "("]


@st.composite
def _hostile(draw):
    parts = []
    for _ in range(draw(st.integers(1, 30))):
        kind = draw(st.integers(0, 3))
        if kind == 0:
            parts.append(draw(st.sampled_from(_ATOMS)))
        elif kind == 1:
            parts.append(draw(st.sampled_from(_OPS)) * draw(st.integers(1, 3)))
        elif kind == 2:
            parts.append(draw(st.sampled_from(_FUNCS)))
        else:
            parts.append(")" * draw(st.integers(1, 3)))
    text = "".join(parts)
    if draw(st.booleans()):  # balance parentheses so more inputs get past the parser
        text += ")" * max(0, text.count("(") - text.count(")"))
    return text


@settings(max_examples=300, deadline=2000, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(_hostile())
def test_fuzz_parse_and_compile_raise_only_config_errors(text):
    t0 = time.perf_counter()
    try:
        expr = parse_expression(text, ["vx", "vy"], {"k": 1e300})
    except ConfigError:
        assert time.perf_counter() - t0 < 2.0
        return
    assert isinstance(expr, sp.Expr)
    assert not expr.has(sp.zoo, sp.oo, -sp.oo, sp.nan)
    try:
        v = compile_expression(expr, ["vx", "vy"])({"vx": np.array([0.0, 1.5, -2.0]),
                                                     "vy": np.array([1.0, -1.0, 1e300])})
    except DroneIdError:
        return
    assert v.shape == (3,) and v.dtype == np.float64
    assert time.perf_counter() - t0 < 2.0


@settings(max_examples=200, deadline=2000, derandomize=True)
@given(st.text(max_size=60))
def test_fuzz_arbitrary_text_raises_only_config_errors(text):
    try:
        parse_expression(text, ["vx"])
    except ConfigError:
        pass


# -- safe_format ---------------------------------------------------------------------------------

def test_safe_format_allows_names_and_bounded_numeric_specs():
    assert safe_format("k = {k:.3g} 1/s, tau {tau}", {"k": 0.28123, "tau": 2.0}) == "k = 0.281 1/s, tau 2.0"
    assert safe_format("{k:>8.2f}|{{literal}}", {"k": 1.0}) == "    1.00|{literal}"


@pytest.mark.parametrize("template, problem", [
    ("{k:>2000000000}", "width"),
    ("{k:.500f}", "precision"),
    ("{k.__class__}", "attribute"),
    ("{k[0]}", "attribute"),
    ("{0}", "name"),
    ("{}", "name"),
    ("{k!r}", "conversion"),
    ("{k:{k}}", "spec"),
    ("{unknown}", "unknown"),
    ("{k", "bad"),
    ("{k:,d}", "spec"),
])
def test_safe_format_rejects(template, problem):
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=problem):
        safe_format(template, {"k": 1.5}, what="effect 'drag' meaning")
    assert time.perf_counter() - t0 < 0.5


def test_effects_toml_rejects_power_tower(tmp_path):
    from priors.effects import load_effects
    p = tmp_path / "fx.toml"
    p.write_text('[[effect]]\nid = "tower"\n[effect.features.vx_dot]\nk = "9**9**9*vx"\n')
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=r"9\*\*9\*\*9"):
        load_effects(p)
    assert time.perf_counter() - t0 < 2.0


def test_safe_format_is_a_drop_in_for_effect_meanings():
    # the templates priors/effects.py documents and ships format the same as str.format
    for template in ("rotor drag k = {k:.3g} 1/s", "cubic drag k3 = {k3:.3g}", "k_D {k_D}"):
        values = {"k": 0.28, "k3": 0.5, "k_D": 0.3}
        assert safe_format(template, values) == template.format(**values)


def test_evaluating_a_non_numeric_column_is_a_data_error():
    from droneid.errors import DataError
    f = compile_expression(symbol("vx") * 2, ["vx"])
    with pytest.raises(DataError, match="not numeric"):
        f({"vx": np.array(["a", "b"])})
    assert f({"vx": [1, 2], "flight": np.array(["f1", "f1"])}).tolist() == [2.0, 4.0]
    assert compile_expression(sp.Integer(3), ["vx"])({"vx": np.zeros(4)}).tolist() == [3.0] * 4
