"""Numbers a reader can read (issue 40.5): exported floats by their shortest round-trip repr, the
motor-speed conversion written as 2π/60 (never π/180's 0.017453292519943295), electrical rpm
named erpm where the log says so."""
import math

import numpy as np
import sympy as sp

from droneid.core.expressions import c_code, octave_code, symbol
from droneid.use.export import c_functions
from droneid.fitting.closed_form import IdentifiedModel
from droneid.logs.flight import Signal
from droneid.simulation.openloop import CRAZYFLIE_RAD_S_PER_ERPM, rad_s_per_rpm_text
from droneid.simulation.simulator import simulate
from droneid.dataset.suitability import prior_for_flights


def test_c_and_matlab_code_print_floats_shortest():
    e = sp.Float(0.7864082395592220) * symbol("vz") - sp.Float(9.81)
    assert "9.81" in c_code(e) and "9.8100000000000005" not in c_code(e)
    assert "0.786408239559222" in c_code(e) and float("0.786408239559222") == 0.786408239559222
    assert "9.8100000000000005" not in octave_code(e)
    m = IdentifiedModel("vz_dot", sp.Float(-0.25) * symbol("vz") - sp.Float(9.81), {}, "test")
    assert "return -0.25*vz - 9.81;" in "\n".join(c_functions([m]))


def test_the_rotor_speed_conversion_reads_as_2pi_over_60():
    assert rad_s_per_rpm_text(2 * math.pi / 60) == "2π/60 rad/s per rpm"
    text = rad_s_per_rpm_text(CRAZYFLIE_RAD_S_PER_ERPM)
    assert text.startswith("2π/(60·6) rad/s per erpm") and "0.0174" not in text


def test_a_rotor_thrust_prior_on_electrical_rpm_says_erpm():
    f = simulate(path="hover", duration_s=10.0, rate_hz=100.0, seed=1).flight
    erpm = f.with_signals(*(Signal(f"rpm{i}", f[f"rpm{i}"].t, 6 * np.asarray(f[f"rpm{i}"].values), "erpm")
                            for i in range(1, 5)))
    prior, _ = prior_for_flights("rotor-thrust", [erpm], 0.05)
    text = " ".join(p.description for p in prior.features("vz_dot"))
    assert "per (10⁴ erpm)²" in text and "(10⁴ rpm)²" not in text
    assert prior.with_params(k_T=0.03).params["rpm_unit"] == "erpm"      # survives hover calibration
    rpm_prior, _ = prior_for_flights("rotor-thrust", [f], 0.05)
    assert "per (10⁴ rpm)²" in " ".join(p.description for p in rpm_prior.features("vz_dot"))
