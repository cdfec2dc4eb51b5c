"""The full 6-DOF export (droneid.export.export_vehicle, issue 28): the generated Python and C step
functions reproduce droneid's own open-loop simulation (openloop.simulate of the same vehicle)
step by step from the motor speeds alone, input conditioning included."""
from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from droneid.errors import ConfigError
from droneid.export import export_vehicle
from droneid.openloop import IdentifiedVehicle, StateLog, simulate
from droneid.rotation import RotationModel, TranslationModel
from priors.torque import get_layout

DT = 0.01
N = 150
TERMS = ("centre", "damping", "gyro", "spinup", "rotor_drag", "rotor_drag_thrust")


def _vehicle():
    """Every rotational term, every input conditioning step (delays, low-pass, centring, balance)."""
    coef = (np.array([6.0, 0.05, 3.0, -0.8, 2.0, 0.1]), np.array([5.0, -0.03, 3.0, 0.9, 1.5, -0.1]),
            np.array([1.5, 0.02, 3.0, -0.1, 0.5]))
    rot = RotationModel(get_layout("crazyflie_x"), TERMS, coef, np.array([0.1, -0.2, 0.05]), delay_steps=2,
                        lowpass_tau_s=0.05, centre_tau_s=2.0, balance_weight_s=1.0,
                        balance_prior=np.array([2.4, 2.5, 2.6, 2.5]))
    return IdentifiedVehicle(TranslationModel(k_thrust=0.83, drag=np.array([0.3, 0.2, 0.1]), delay_steps=3), rot)


def _case():
    rng = np.random.default_rng(7)
    rpm = 95000.0 + np.cumsum(rng.normal(0.0, 300.0, (N + 1, 4)), axis=0)
    x0 = np.array([0.1, -0.2, 1.0, 0.5, -0.3, 0.1, np.cos(0.1), 0.05, -0.03, np.sin(0.1), 0.3, -0.2, 0.1])
    x0[6:10] /= np.linalg.norm(x0[6:10])
    veh = _vehicle()
    u = veh.inputs(StateLog("case", DT * np.arange(N + 1), np.zeros((N + 1, 13)), rpm, DT))
    ref = simulate(veh, x0[None], u[None, :N], DT)[0]
    return veh, rpm, x0, ref


def test_python_export_steps_as_droneid_simulates():
    veh, rpm, x0, ref = _case()
    ns: dict = {}
    exec(compile(export_vehicle(veh.translation, veh.rotation, "python"), "vehicle.py", "exec"), ns)
    cond, x = ns["Inputs"](), list(x0)
    for k in range(N):
        x = ns["step"](x, cond.push(rpm[k]))
        np.testing.assert_allclose(x, ref[k], rtol=1e-9, atol=1e-9, err_msg=f"step {k}")
    assert abs(np.linalg.norm(x[6:10]) - 1.0) < 1e-12
    assert np.ptp(ref[:, 10:13], axis=0).min() > 0.05     # the rates move: the rotation is exercised


def test_c_export_compiles_and_steps_as_droneid_simulates(tmp_path):
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        pytest.skip("no C compiler (cc, gcc or clang) on this machine")
    veh, rpm, x0, ref = _case()
    (tmp_path / "vehicle.c").write_text(export_vehicle(veh.translation, veh.rotation, "c"))
    rows = ",\n".join("{" + ", ".join(repr(float(v)) for v in r) + "}" for r in rpm[:N])
    (tmp_path / "main.c").write_text(f'''#include <stdio.h>
#include "vehicle.c"
static const double RPM[{N}][4] = {{{rows}}};
int main(void)
{{
    double x[13] = {{{", ".join(repr(float(v)) for v in x0)}}};
    double u[DRONEID_U];
    droneid_inputs c;
    int k, i;
    droneid_inputs_init(&c, DRONEID_DT);
    for (k = 0; k < {N}; k++) {{
        droneid_inputs_push(&c, RPM[k], u);
        droneid_step(x, u, DRONEID_DT);
        for (i = 0; i < 13; i++) printf("%.17g%c", x[i], i == 12 ? '\\n' : ' ');
    }}
    return 0;
}}
''')
    exe = tmp_path / "vehicle"
    subprocess.run([cc, "-std=c99", "-Wall", "-Werror", "-O2", "-o", str(exe), str(tmp_path / "main.c"), "-lm"],
                   check=True, capture_output=True, text=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    got = np.array([[float(v) for v in line.split()] for line in out.strip().splitlines()])
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)


def test_export_vehicle_refuses_other_models_and_formats():
    veh = _vehicle()
    with pytest.raises(ConfigError, match="TranslationModel"):
        export_vehicle(object(), veh.rotation, "python")
    with pytest.raises(ConfigError, match="python"):
        export_vehicle(veh.translation, veh.rotation, "pyhton")
