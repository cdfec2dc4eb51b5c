"""The full 6-DOF export (droneid.use.vehicle_export.export_vehicle, issue 28): the generated Python and C step
functions reproduce droneid's own open-loop simulation (openloop.simulate of the same vehicle)
step by step from the motor speeds alone, input conditioning included."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.errors import ConfigError
from droneid.use.vehicle_export import export_vehicle
from droneid.simulation.openloop import IdentifiedVehicle, StateLog, simulate
from droneid.rotation.model import RotationModel, TranslationModel
from priors.torque import get_layout

from export_helpers import CC, vehicle_c_rollout, vehicle_python_rollout

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
    got = vehicle_python_rollout(export_vehicle(veh.translation, veh.rotation, "python"), rpm, x0, 0, N)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)
    x = got[-1]
    assert abs(np.linalg.norm(x[6:10]) - 1.0) < 1e-12
    assert np.ptp(ref[:, 10:13], axis=0).min() > 0.05     # the rates move: the rotation is exercised


def test_c_export_compiles_and_steps_as_droneid_simulates(tmp_path):
    if CC is None:
        pytest.skip("no C compiler (gcc / cc) on this machine")
    veh, rpm, x0, ref = _case()
    got = vehicle_c_rollout(tmp_path, export_vehicle(veh.translation, veh.rotation, "c"), rpm, x0, 0, N)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)


def test_export_vehicle_refuses_other_models_and_formats():
    veh = _vehicle()
    with pytest.raises(ConfigError, match="TranslationModel"):
        export_vehicle(object(), veh.rotation, "python")
    with pytest.raises(ConfigError, match="python"):
        export_vehicle(veh.translation, veh.rotation, "pyhton")
