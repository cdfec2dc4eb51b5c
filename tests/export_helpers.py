"""Helpers of the ``droneid export`` tests (tests/integration/test_export.py and
tests/real_logs/test_export_real.py): a model to export, a result file holding it, the CLI call,
and loading the exported Python module or compiled C library to evaluate it."""
from __future__ import annotations

import ctypes
import importlib.util
import json
import shutil
import subprocess

import numpy as np
import sympy as sp

from droneid.cli import main
from droneid.closed_form import IdentifiedModel

CC = shutil.which("gcc") or shutil.which("cc")


def rotor_thrust_sum(target: str) -> IdentifiedModel:
    from priors.registry import get_prior
    p = get_prior("rotor-thrust", source="rpm", motors=4)
    return IdentifiedModel(target, sp.Add(*[f.expr for f in p.features(target)]), {"rpm1": 0.02},
                           "rotor-thrust prior, summed")


def write_result(tmp_path, models) -> str:
    path = tmp_path / "result.json"
    path.write_text(json.dumps({"schema": "droneid.identify/2", "targets": {m.target: {"final": m.to_dict()} for m in models},
                                "config": {"ts": 0.01, "method": "forward"}}))
    return str(path)


def export_cli(tmp_path, result, to, name) -> str:
    out = tmp_path / name
    assert main(["export", result, "--to", to, "-o", str(out)]) == 0
    return str(out)


def python_module(path):
    spec = importlib.util.spec_from_file_location("exported_models", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def c_library(tmp_path, c_path):
    so = tmp_path / "models.so"
    subprocess.run([CC, "-std=c99", "-O0", "-shared", "-fPIC", c_path, "-o", str(so), "-lm"], check=True)
    return ctypes.CDLL(str(so))


def c_eval(lib, m: IdentifiedModel, cols) -> np.ndarray:
    fn = getattr(lib, m.target)
    fn.restype = ctypes.c_double
    fn.argtypes = [ctypes.c_double] * len(m.signals)
    args = [np.asarray(cols[s], float) for s in m.signals]
    return np.array([fn(*(float(a[i]) for a in args)) for i in range(len(args[0]))])
