"""``droneid export``: the exported code computes what ``predict`` computes.

Python is imported and C compiled (the machine's C compiler; skipped where absent) and both are
evaluated on the same columns as :class:`IdentifiedModel.evaluate` (what ``predict`` calls):
agreement to 1e-9 relative, on random inputs and on a real Crazyflie log.
"""
from __future__ import annotations

import ctypes
import importlib.util
import json
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp

from droneid.cli import main
from droneid.errors import ConfigError
from droneid.export import FORMATS, export_models
from droneid.identified import IdentifiedModel

from conftest import real_log

CC = shutil.which("gcc") or shutil.which("cc")


def _rotor_thrust(target: str) -> IdentifiedModel:
    from priors.models import get_prior
    p = get_prior("rotor-thrust", source="rpm", motors=4)
    return IdentifiedModel(target, sp.Add(*[f.expr for f in p.features(target)]), {"rpm1": 0.02},
                           "rotor-thrust prior, summed")


def _result(tmp_path, models) -> str:
    path = tmp_path / "result.json"
    path.write_text(json.dumps({"targets": {m.target: {"final": m.to_dict()} for m in models},
                                "config": {"ts": 0.01, "method": "forward"}}))
    return str(path)


def _export(tmp_path, result, to, name) -> str:
    out = tmp_path / name
    assert main(["export", result, "--to", to, "-o", str(out)]) == 0
    return str(out)


def _python_module(path):
    spec = importlib.util.spec_from_file_location("exported_models", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _c_library(tmp_path, c_path):
    so = tmp_path / "models.so"
    subprocess.run([CC, "-std=c99", "-O0", "-shared", "-fPIC", c_path, "-o", str(so), "-lm"], check=True)
    return ctypes.CDLL(str(so))


def _c_eval(lib, m: IdentifiedModel, cols) -> np.ndarray:
    fn = getattr(lib, m.target)
    fn.restype = ctypes.c_double
    fn.argtypes = [ctypes.c_double] * len(m.signals)
    args = [np.asarray(cols[s], float) for s in m.signals]
    return np.array([fn(*(float(a[i]) for a in args)) for i in range(len(args[0]))])


def _random_columns(models, n=500, seed=0):
    rng = np.random.default_rng(seed)
    names = sorted({s for m in models for s in m.signals})
    scale = {"roll": 0.5, "pitch": 0.5, "yaw": 3.0, "vx": 2.0, "vy": 2.0, "vz": 1.0}
    return {s: rng.uniform(-1, 1, n) * scale.get(s, 1.0) if not s.startswith("rpm") else rng.uniform(1e4, 3e4, n)
            for s in names}


def test_header_states_inputs_units_conventions_delays_and_source(tmp_path):
    models = [_rotor_thrust("vx_dot"), _rotor_thrust("vz_dot")]
    result = _result(tmp_path, models)
    for to in FORMATS:
        text = open(_export(tmp_path, result, to, {"python": "m.py", "c": "m.c", "matlab": "m.m",
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
    models = [_rotor_thrust("vx_dot"), _rotor_thrust("vz_dot"), odd]
    result = _result(tmp_path, models)
    py = _python_module(_export(tmp_path, result, "python", "models.py"))
    cols = _random_columns(models)
    for m in models:
        want = m.evaluate(cols)
        got = getattr(py, m.target)(**{s: cols[s] for s in m.signals})
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=0)
    if CC is None:
        pytest.skip("no C compiler (gcc / cc) on this machine")
    lib = _c_library(tmp_path, _export(tmp_path, result, "c", "models.c"))
    for m in models:
        np.testing.assert_allclose(_c_eval(lib, m, cols), m.evaluate(cols), rtol=1e-9, atol=0)


def test_constant_model_and_bad_requests(tmp_path, capsys):
    zero = IdentifiedModel("vz_dot", sp.Float(0.0), description="v̇z = 0")
    mod_path = tmp_path / "zero.py"
    mod_path.write_text(export_models([zero], "python"))
    assert _python_module(mod_path).vz_dot(vz=1.0) == 0.0
    with pytest.raises(ConfigError, match="'to'"):
        export_models([zero], "fortran")
    with pytest.raises(ConfigError, match="MATLAB identifier"):
        export_models([zero], "matlab", name="1x")
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"targets": {"vx_dot": {"model": {"x": 1}, "inputs": ["vx"]}}}))
    assert main(["export", str(old), "--to", "c"]) == 2
    err = capsys.readouterr().err
    assert "old.json" in err and "no final model" in err and "Traceback" not in err


@pytest.mark.real_logs
def test_exported_code_matches_predict_on_a_real_crazyflie_log(tmp_path):
    """The rotor-thrust prior summed, on the Crazyflie square_run2 log at its 100 Hz: the values
    ``predict`` computes (IdentifiedModel.evaluate on the dataset it builds), the exported Python
    and the compiled C agree to 1e-9 relative."""
    from droneid.dataset import DatasetBuilder
    from droneid.predict import _predict_final
    from parsers import read_flight
    flight = read_flight(real_log("mocap/crazyflie_nanodrone/square_run2.csv"))
    m = IdentifiedModel("vx_dot", _rotor_thrust("vx_dot").expr, description="rotor-thrust prior, summed")
    ds, preds, _ = _predict_final(DatasetBuilder(ts=0.01, method="forward"), [flight], "vx_dot", {"identified": m})
    cols = ds.columns()
    want = preds["identified"]
    assert len(ds) > 1500 and np.isfinite(want).all() and np.std(want) > 0.1
    result = _result(tmp_path, [m])
    py = _python_module(_export(tmp_path, result, "python", "cf.py"))
    np.testing.assert_allclose(py.vx_dot(**{s: cols[s] for s in m.signals}), want, rtol=1e-9, atol=0)
    if CC is None:
        pytest.skip("no C compiler (gcc / cc) on this machine")
    lib = _c_library(tmp_path, _export(tmp_path, result, "c", "cf.c"))
    np.testing.assert_allclose(_c_eval(lib, m, cols), want, rtol=1e-9, atol=0)
