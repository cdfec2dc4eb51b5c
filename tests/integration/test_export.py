"""``droneid export``: the exported code computes what ``predict`` computes.

Python is imported and C compiled (the machine's C compiler; skipped where absent) and both are
evaluated on the same columns as :class:`IdentifiedModel.evaluate` (what ``predict`` calls):
agreement to 1e-9 relative, on random inputs (on a real Crazyflie log:
tests/real_logs/test_export_real.py).
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp

from droneid.cli import main
from droneid.errors import ConfigError
from droneid.use.export import FORMATS, export_models
from droneid.fitting.closed_form import IdentifiedModel

from export_helpers import (CC, c_eval, c_library, export_cli, python_module, rotor_thrust_sum,
                            write_result)


def _random_columns(models, n=500, seed=0):
    rng = np.random.default_rng(seed)
    names = sorted({s for m in models for s in m.signals})
    scale = {"roll": 0.5, "pitch": 0.5, "yaw": 3.0, "vx": 2.0, "vy": 2.0, "vz": 1.0}
    return {s: rng.uniform(-1, 1, n) * scale.get(s, 1.0) if not s.startswith("rpm") else rng.uniform(1e4, 3e4, n)
            for s in names}


def test_header_states_inputs_units_conventions_delays_and_source(tmp_path):
    models = [rotor_thrust_sum("vx_dot"), rotor_thrust_sum("vz_dot")]
    result = write_result(tmp_path, models)
    for to in FORMATS:
        text = open(export_cli(tmp_path, result, to, {"python": "m.py", "c": "m.c", "matlab": "m.m",
                                                       "latex": "m.tex"}[to])).read()
        for must in ("ENU", "FLU", "Z-Y-X", "positive = nose down", "rpm1 [rpm]", "roll [rad]", "vx [m/s]",
                     "feed rpm1 at t - 0.02 s", "droneid 0.1.0", "result.json", "vz_dot (m/s^2) ="):
            assert must in text, (to, must)
    assert "function m = m()" in open(tmp_path / "m.m").read()
    assert r"\dot{v_x}" in open(tmp_path / "m.tex").read() and r"\phi" in open(tmp_path / "m.tex").read()


def test_exported_python_and_c_match_evaluate_on_random_inputs(tmp_path):
    x, vx = sp.symbols("roll vx")
    odd = IdentifiedModel("vy_dot", sp.tanh(x) * sp.Abs(vx) ** 1.5 - sp.exp(-vx ** 2) / (2 + sp.cos(x))
                          + sp.sqrt(sp.Abs(x)))
    models = [rotor_thrust_sum("vx_dot"), rotor_thrust_sum("vz_dot"), odd]
    result = write_result(tmp_path, models)
    py = python_module(export_cli(tmp_path, result, "python", "models.py"))
    cols = _random_columns(models)
    for m in models:
        want = m.evaluate(cols)
        got = getattr(py, m.target)(**{s: cols[s] for s in m.signals})
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=0)
    if CC is None:
        pytest.skip("no C compiler (gcc / cc) on this machine")
    lib = c_library(tmp_path, export_cli(tmp_path, result, "c", "models.c"))
    for m in models:
        np.testing.assert_allclose(c_eval(lib, m, cols), m.evaluate(cols), rtol=1e-9, atol=0)


def test_constant_model_and_bad_requests(tmp_path, capsys):
    zero = IdentifiedModel("vz_dot", sp.Float(0.0), description="v̇z = 0")
    mod_path = tmp_path / "zero.py"
    mod_path.write_text(export_models([zero], "python"))
    assert python_module(mod_path).vz_dot(vz=1.0) == 0.0
    with pytest.raises(ConfigError, match="'to'"):
        export_models([zero], "fortran")
    with pytest.raises(ConfigError, match="MATLAB identifier"):
        export_models([zero], "matlab", name="1x")
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"schema": "droneid.identify/1",
                               "targets": {"vx_dot": {"model": {"x": 1}, "inputs": ["vx"]}}}))
    assert main(["export", str(old), "--to", "c"]) == 2
    err = capsys.readouterr().err
    assert "old.json" in err and "re-run `droneid identify`" in err and "Traceback" not in err
