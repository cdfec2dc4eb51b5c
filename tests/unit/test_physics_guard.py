"""The physics guard on found terms (droneid.fitting.physics_guard): one motor alone, absolute position,
mixed units are refused whoever found the term (identify's ladder, diagnose's open-ended search)."""
import pytest
import sympy as sp

from droneid.identify.ladder import evolved_labels
from droneid.fitting.physics_guard import ACCELERATION, dimension, term_problem
from droneid.diagnosis.residual_search import physics_refusal

MOTORS = ["rpm1", "rpm2", "rpm3", "rpm4", "vx", "vz", "pitch", "roll", "x", "y", "z"]
E = sp.sympify


@pytest.mark.parametrize("term, words", [
    ("-rpm2", "rpm2 but not rpm1, rpm3, rpm4"),          # make demo's first evolved term
    ("rpm1**2*cos(pitch)", "one motor"),
    ("x*vx", "absolute position (x)"),
    ("y", "absolute position (y)"),
    ("z*vz", "height z"),
    ("vx + pitch", "different units"),
    ("sin(vx)", "sin of a quantity with a unit"),
    ("exp(rpm1*rpm2*rpm3*rpm4)", "exp of a quantity with a unit"),
    ("P + vx", "different units"),
])
def test_refused_terms_say_why(term, words):
    why = term_problem(E(term), MOTORS, symbols={"P": ACCELERATION})
    assert why is not None and words in why


@pytest.mark.parametrize("term", ["(rpm1**2 + rpm2**2 + rpm3**2 + rpm4**2)*cos(pitch)", "vx*Abs(vx)",
                                  "sin(pitch)*vx", "vx - 0.5", "P*vz", "(P - 2.25 + pi)**4", "tanh(pitch)*roll"])
def test_physical_terms_pass(term):
    assert term_problem(E(term), MOTORS, symbols={"P": ACCELERATION}) is None


def test_one_motor_is_allowed_once_the_per_motor_effect_was_found_and_height_near_the_ground():
    assert term_problem(E("rpm2**2"), MOTORS, per_motor=True) is None
    assert term_problem(E("vz/(1 + z**2)"), MOTORS, height=True) is None
    assert term_problem(E("x"), MOTORS, per_motor=True, height=True) is not None


def test_dimension_of_a_rotor_thrust_term():
    assert dimension(E("rpm1**2 + rpm2**2")) == (0, -2, 0, 0, 0)
    assert dimension(E("vx*sin(pitch)")) == (1, -1, 0, 0, 0)
    assert dimension(E("vx*unknown_signal")) is None


def test_an_evolved_term_with_a_leading_minus_is_negated_not_double_signed():
    """make demo printed ``-1.913e-05·-rpm2``: the label keeps no sign, the coefficient carries it."""
    terms, labels = evolved_labels([E("-rpm2"), E("-P*vx")], {"P": "sum_rpm_sq_z"})
    assert labels == ["rpm2", "⟨sum_rpm_sq_z⟩*vx"]
    assert terms == [E("rpm2"), E("P*vx")]


def test_the_open_ended_search_refuses_a_single_motor_equation():
    why = physics_refusal(E("0.3 + 2e-5*rpm2 - 0.1*vx"), MOTORS)
    assert why and "rpm2" in why and "physics guard" in why
    assert physics_refusal(E("0.3 - 0.1*vx*Abs(vx)"), MOTORS) is None


def test_the_open_ended_search_judges_terms_unexpanded_as_identify_does():
    """melon_run4 (issue 40.1): diagnose called ``0.2795*vx*(vx + z) − 0.1425*(vx + z)**2`` a
    significant residual; expanded, every addend (vx², vx·z, z²) is unit-consistent on its own,
    so the guard judged the expansion and missed that each term adds a velocity to a height.
    Judged as the engine's terms (as identify's ladder does), both are refused."""
    eq = E("0.2795*vx*(vx + z) - 0.1425*(vx + z)**2")
    why = physics_refusal(eq, MOTORS, height=True)
    assert why and "different units" in why and "vx + z" in why
    # the SNGP model's own terms, as the search passes them
    why = physics_refusal([E("vx*(vx + z)"), E("vx*Abs(vx)")], MOTORS, height=True)
    assert why and "vx*(vx + z)" in why
    assert physics_refusal([E("vx*Abs(vx)"), E("(rpm1**2 + rpm2**2 + rpm3**2 + rpm4**2)*sin(pitch)")],
                           MOTORS) is None
