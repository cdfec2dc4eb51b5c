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
from droneid.fitting.closed_form import IdentifiedModel

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


# -- the whole vehicle (export --vehicle) ----------------------------------------------------------
def vehicle_python_rollout(text: str, rpm, x0, start: int, steps: int, u_ref=None) -> np.ndarray:
    """States (steps, 13) of an exported Python vehicle: its conditioner fed ``rpm[0:start]``
    first (the history a window's delays and balance read), then stepped from ``x0`` with
    ``rpm[start:start + steps]``; ``u_ref`` (N, U), if given, must equal each step's inputs."""
    ns: dict = {}
    exec(compile(text, "vehicle.py", "exec"), ns)
    cond = ns["Inputs"]()
    for k in range(start):
        cond.push(rpm[k])
    x, out = list(x0), []
    for k in range(start, start + steps):
        u = cond.push(rpm[k])
        if u_ref is not None:
            np.testing.assert_allclose(u, u_ref[k], rtol=1e-12, atol=1e-12, err_msg=f"inputs at step {k}")
        x = ns["step"](x, u)
        out.append(x)
    return np.array(out)


def vehicle_c_rollout(tmp_path, text: str, rpm, x0, start: int, steps: int) -> np.ndarray:
    """:func:`vehicle_python_rollout` of an exported C vehicle, compiled with gcc
    ``-std=c99 -Wall -Werror`` (a warning fails the build) and run with a small main."""
    rpm = np.asarray(rpm, float)[:start + steps]
    (tmp_path / "vehicle.c").write_text(text)
    rows = ",\n".join("{" + ", ".join(repr(float(v)) for v in r) + "}" for r in rpm)
    (tmp_path / "main.c").write_text(f'''#include <stdio.h>
#include "vehicle.c"
static const double RPM[{rpm.shape[0]}][{rpm.shape[1]}] = {{{rows}}};
int main(void)
{{
    double x[13] = {{{", ".join(repr(float(v)) for v in x0)}}};
    double u[DRONEID_U];
    droneid_inputs c;
    int k, i;
    droneid_inputs_init(&c, DRONEID_DT);
{f"    for (k = 0; k < {start}; k++) droneid_inputs_push(&c, RPM[k], u);" if start else ""}
    for (k = {start}; k < {start + steps}; k++) {{
        droneid_inputs_push(&c, RPM[k], u);
        droneid_step(x, u, DRONEID_DT);
        for (i = 0; i < 13; i++) printf("%.17g%c", x[i], i == 12 ? '\\n' : ' ');
    }}
    return 0;
}}
''')
    exe = tmp_path / "vehicle"
    build = subprocess.run([CC, "-std=c99", "-Wall", "-Werror", "-o", str(exe), str(tmp_path / "main.c"), "-lm"],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    return np.array([[float(v) for v in line.split()] for line in out.strip().splitlines()])
