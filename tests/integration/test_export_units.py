"""Export headers say what each input is (issue 29, item 7): the unit the data had (eRPM named as
such), the raw log field and the normalisation the reader applied, from the provenance a result
records; the equations in C and MATLAB headers are written in C and MATLAB (no Python ``**``)."""
from __future__ import annotations

import json

import numpy as np

from droneid.use.export import input_sources
from parsers import read_flight

from export_helpers import export_cli, rotor_thrust_sum


def _motor_model():
    import sympy as sp

    from droneid.fitting.closed_form import IdentifiedModel
    from priors.registry import get_prior
    p = get_prior("rotor-thrust", source="motor", motors=4)
    return IdentifiedModel("vz_dot", sp.Add(*[f.expr for f in p.features("vz_dot")]), {}, "motor commands")


def _result_with_provenance(tmp_path, flights, models=None) -> str:
    from dataclasses import asdict
    models = models or [rotor_thrust_sum("vz_dot")]
    path = tmp_path / "result.json"
    path.write_text(json.dumps({"schema": "droneid.identify/2", "targets": {m.target: {"final": m.to_dict()} for m in models},
                                "config": {"ts": 0.01}, "provenance": {
                                    "train": [asdict(f.provenance) for f in flights], "test": []}}))
    return str(path)


def _crazyflie_like_csv(tmp_path):
    t = np.arange(300) * 0.01
    rows = ["t,x,y,z,m1_erpm,m2_erpm,m3_erpm,m4_erpm,m1_thrust"]
    rows += [f"{a:.2f},0,0,1,{20000 + a:.0f},{20000 + a:.0f},{20000 + a:.0f},{20000 + a:.0f},{0.5 + 0.1 * np.sin(a):.4f}"
             for a in t]
    p = tmp_path / "cf.csv"
    p.write_text("\n".join(rows) + "\n")
    return p


def test_header_names_erpm_and_the_raw_field(tmp_path):
    f = read_flight(_crazyflie_like_csv(tmp_path))
    assert f["rpm1"].unit == "erpm" and "electrical rpm" in f["rpm1"].source
    result = _result_with_provenance(tmp_path, [f])
    for to, name in (("python", "m.py"), ("c", "m.c"), ("matlab", "m.m"), ("latex", "m.tex")):
        text = open(export_cli(tmp_path, result, to, name)).read()
        assert "rpm1 [erpm] from m1_erpm (electrical rpm: rpm x motor pole pairs; the log states no " \
               "pole-pair count)" in text, (to, text[:1500])
        assert "rpm1 [rpm]" not in text
    for name in ("m.c", "m.m"):
        text = open(tmp_path / name).read()
        assert "**" not in text, name          # C and MATLAB syntax, header comments included
    assert "pow(" in open(tmp_path / "m.c").read().split("*/")[0]
    assert ".^" in open(tmp_path / "m.m").read().split("function out")[0] or "^" in open(tmp_path / "m.m").read()


def test_pwm_normalisation_from_the_log_is_stated(tmp_path):
    """A DataFlash motor (log171): the header says which RCOU channel and which PWM range made
    motor1 0..1."""
    from conftest import real_log
    f = read_flight(real_log("ardupilot/copter33_quad_log171.bin"))
    result = _result_with_provenance(tmp_path, [f], [_motor_model()])
    text = open(export_cli(tmp_path, result, "c", "m.c")).read()
    line = next(ln for ln in text.splitlines() if "motor1 [1] from" in ln)
    src = input_sources({"train": [{"signal_sources": [list(r) for r in f.provenance.signal_sources]}]})
    assert src["motor1"][0][0] == "1" and src["motor1"][0][1].startswith("RCOU.Ch1 (PWM ")
    assert "-> 0..1" in src["motor1"][0][1]
    assert "RCOU.Ch1 (PWM " in line and "-> 0..1" in line, line


def test_input_sources_lists_each_reading_once():
    prov = {"train": [{"signal_sources": [["rpm1", "erpm", "m1_erpm (electrical rpm)"]]},
                      {"signal_sources": [["rpm1", "erpm", "m1_erpm (electrical rpm)"]]},
                      {"signal_sources": [["rpm1", "rpm", "ESC.RPM"]]}], "test": None}
    assert input_sources(prov) == {"rpm1": [("erpm", "m1_erpm (electrical rpm)"), ("rpm", "ESC.RPM")]}
    assert input_sources(None) == {} and input_sources({"train": [{"signal_sources": [["x", 1, None]]}]}) == {}


def test_no_python_power_in_c_or_matlab_headers_even_in_a_description(tmp_path):
    import sympy as sp

    from droneid.fitting.closed_form import IdentifiedModel
    vx = sp.Symbol("vx")
    m = IdentifiedModel("vx_dot", -0.3 * vx ** 2, {}, "drag: -0.3*vx**2 fitted")
    path = tmp_path / "result.json"
    path.write_text(json.dumps({"schema": "droneid.identify/2", "targets": {"vx_dot": {"final": m.to_dict()}},
                                "config": {"ts": 0.01}}))
    for to, name in (("c", "m.c"), ("matlab", "m.m")):
        text = open(export_cli(tmp_path, str(path), to, name)).read()
        assert "**" not in text, (to, text[:800])
    assert "vx**2" in open(export_cli(tmp_path, str(path), "python", "m.py")).read()
