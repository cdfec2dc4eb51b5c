"""``droneid export RESULT.json --vehicle`` (issue 28): identify's final v̇ models and the result's
rotational model as one 6-DOF step function in Python and C.

Planted vehicle: v̇ models of identify's form (thrust along the tilted body z from the squared
motor speeds, each model with its own per-motor delays, linear drag, g fixed) and a rotational
model with every term and every input conditioning step. The exported code is fed the motor
speeds from the first step of a synthetic log and stepped from the true state at a later start;
it must reproduce droneid's own open-loop rollout (``IdentifiedVehicle(IdentifiedTranslation(models),
rotation)`` by ``openloop.simulate``, the model ``predict --open-loop`` scores) to 1e-9 over 50
steps. The C is compiled with ``-std=c99 -Wall -Werror`` and must match the Python.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from droneid.cli import main
from droneid.fitting.closed_form import IdentifiedModel
from droneid.errors import ConfigError
from droneid.use.vehicle_export import export_vehicle
from droneid.simulation.openloop import IdentifiedTranslation, IdentifiedVehicle, StateLog, simulate
from droneid.rotation.model import RotationModel
from priors.torque import get_layout

from export_helpers import CC, vehicle_c_rollout, vehicle_python_rollout

DT = 0.01
N = 260          # log length (steps)
START = 200      # the window starts here: the conditioner has been fed 200 steps of history
H = 50           # steps stepped open loop
TERMS = ("centre", "damping", "gyro", "spinup", "rotor_drag", "rotor_drag_thrust")


def _translation() -> dict:
    """v̇ of identify's form; delays differ per model and per motor (0 to 40 ms)."""
    vx, vy, vz, roll, pitch, yaw = sp.symbols("vx vy vz roll pitch yaw")
    rpm = sp.symbols("rpm1:5")
    thrust = 2.7e-10 * sum(r ** 2 for r in rpm)
    return {
        "vx_dot": IdentifiedModel("vx_dot", -0.18 * vx + (sp.sin(pitch) * sp.cos(roll) * sp.cos(yaw)
                                                          + sp.sin(roll) * sp.sin(yaw)) * thrust,
                                  {"rpm1": 0.03, "rpm2": 0.03, "rpm3": 0.02, "rpm4": 0.04}),
        "vy_dot": IdentifiedModel("vy_dot", -0.17 * vy + (sp.sin(pitch) * sp.sin(yaw) * sp.cos(roll)
                                                          - sp.sin(roll) * sp.cos(yaw)) * thrust,
                                  {"rpm1": 0.01, "rpm2": 0.01, "rpm3": 0.01, "rpm4": 0.01}),
        "vz_dot": IdentifiedModel("vz_dot", -0.44 * vz + sp.cos(pitch) * sp.cos(roll) * thrust
                                  + 0.05 * sp.tanh(vx) - 9.81, {"rpm2": 0.03}),
    }


def _rotation(kind: str = "rigid") -> RotationModel | None:
    """``rigid``: every rigid-body term and every conditioning step (delay, low-pass, centring,
    balance); ``closed-loop``: rate damping and the pull back to a level attitude (term
    ``attitude``, roll and pitch, which reads the simulated attitude); ``held``: None."""
    if kind == "held":
        return None
    if kind == "closed-loop":
        import droneid.rotation.model
        if "attitude" not in getattr(droneid.rotation.model, "CLOSED_LOOP_TERMS", ()):
            pytest.skip("droneid.rotation.model has no closed-loop attitude term in this tree")
        coef = (np.array([4.0, 3.0, 30.0]), np.array([3.0, 2.5, 25.0]), np.array([1.0, 1.5]))
        return RotationModel(get_layout("crazyflie_x"), ("damping", "attitude"), coef, np.array([0.05, -0.1, 0.02]),
                             delay_steps=1, rad_s_per_rpm=2 * np.pi / 360.0, level_rad=np.array([0.01, -0.02]))
    coef = (np.array([6.0, 0.05, 3.0, -0.8, 2.0, 0.1]), np.array([5.0, -0.03, 3.0, 0.9, 1.5, -0.1]),
            np.array([1.5, 0.02, 3.0, -0.1, 0.5]))
    return RotationModel(get_layout("crazyflie_x"), TERMS, coef, np.array([0.1, -0.2, 0.05]), delay_steps=2,
                         lowpass_tau_s=0.05, centre_tau_s=2.0, balance_weight_s=1.0,
                         balance_prior=np.array([2.4, 2.5, 2.6, 2.5]), rad_s_per_rpm=2 * np.pi / 360.0)


def _log() -> StateLog:
    """Motor speeds near hover (erpm, random walk) and a tilted, moving, rotating true state at
    every step (only the state at START is used: the initial state of the window)."""
    rng = np.random.default_rng(11)
    rpm = 95000.0 + np.cumsum(rng.normal(0.0, 400.0, (N, 4)), axis=0)
    state = np.zeros((N, 13))
    q = np.array([np.cos(0.15), 0.06, -0.04, np.sin(0.15)])
    state[:] = np.concatenate([[0.1, -0.2, 1.0, 0.6, -0.4, 0.1], q / np.linalg.norm(q), [0.3, -0.2, 0.4]])
    return StateLog("synthetic", DT * np.arange(N), state, rpm, DT)


KINDS = ["rigid", "closed-loop", "held"]


def _reference(rotation):
    """droneid's own open-loop rollout of the window (H, 13) and the model inputs of the log."""
    tr = IdentifiedTranslation(_translation())
    veh = tr if rotation is None else IdentifiedVehicle(tr, rotation)
    log = _log()
    u = veh.inputs(log)
    return log, u, simulate(veh, log.state[START][None], u[None, START:START + H], DT)[0]


def _python_rollout(text, log, u_ref=None):
    return vehicle_python_rollout(text, log.rpm, log.state[START], START, H, u_ref)


@pytest.mark.parametrize("kind", KINDS)
def test_python_vehicle_reproduces_the_open_loop_rollout(kind):
    rotation = _rotation(kind)
    log, u, ref = _reference(rotation)
    got = _python_rollout(export_vehicle(_translation(), rotation, "python", dt_s=DT), log, u)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)
    assert np.linalg.norm(ref[-1, 0:3] - log.state[START, 0:3]) > 0.02      # the vehicle moved
    assert np.ptp(ref[:, 3:6], axis=0).max() > 0.05                         # the velocity changed
    if rotation is not None:
        assert np.ptp(ref[:, 10:13], axis=0).min() > 0.05                   # every rate moved
    else:
        np.testing.assert_array_equal(got[:, 10:13], np.repeat(log.state[START:START + 1, 10:13], H, axis=0))


@pytest.mark.parametrize("kind", KINDS)
def test_c_vehicle_compiles_strictly_and_steps_as_the_python(tmp_path, kind):
    if CC is None:
        pytest.skip("no C compiler (gcc / cc) on this machine: the C export cannot be compiled here")
    rotation = _rotation(kind)
    log, _, ref = _reference(rotation)
    py = _python_rollout(export_vehicle(_translation(), rotation, "python", dt_s=DT), log)
    got = vehicle_c_rollout(tmp_path, export_vehicle(_translation(), rotation, "c", dt_s=DT), log.rpm,
                            log.state[START], START, H)
    np.testing.assert_allclose(got, py, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)


def test_header_states_layout_units_frames_step_and_delays_in_steps():
    text = export_vehicle(_translation(), _rotation(), "c", dt_s=DT)
    for must in ("State x[13]: p (m, world ENU) 0:3", "w (rad/s, body FLU) 10:13", "ENU", "FLU",
                 "Step: dt = 0.01 s", "returns u[20]", "u[0:4] (vx_dot): rpm1 of 3 step(s) earlier, rpm2 of 3 step(s) "
                 "earlier, rpm3 of 2 step(s) earlier, rpm4 of 4 step(s) earlier", "(vz_dot): rpm1 of 0 step(s)",
                 "rpm2 of 3 step(s)", "feed rpm3 at t - 0.02 s", "vz_dot (m/s^2) =", "rotor layout crazyflie_x",
                 "the motor speeds of 2 step(s) earlier", "low-passed (first order, time constant 0.05 s)",
                 "quaternion renormalised at every stage", "double vx_dot(double pitch, double roll, double rpm1"):
        assert must in text, must
    assert "**" not in text and "pow(rpm1, 2)" in text      # the header's equations in C's own syntax
    held = export_vehicle(_translation(), None, "python", dt_s=DT)
    assert "every body rate is held, w' = 0" in held and "U = 12" in held


def test_a_delay_off_the_grid_is_rounded_and_said_and_a_negative_one_refused():
    models = _translation()
    text = export_vehicle(models, None, "python", dt_s=0.02)
    assert "the delay of rpm1 (0.03 s) is rounded to 2 step(s) of 0.02 s" in text   # as openloop rounds
    ahead = dict(models, vy_dot=IdentifiedModel("vy_dot", models["vy_dot"].expr, {"rpm1": -0.02}))
    with pytest.raises(ConfigError, match="reads rpm1 0.02 s ahead"):
        export_vehicle(ahead, None, "python", dt_s=DT)
    with pytest.raises(ConfigError, match="vz_dot"):
        export_vehicle({t: m for t, m in models.items() if t != "vz_dot"}, None, "c", dt_s=DT)
    with pytest.raises(ConfigError, match="dt_s"):
        export_vehicle(models, None, "c", dt_s=0.0)


# -- the command line ------------------------------------------------------------------------------
def _result(tmp_path, models, rotation="held", horizons=True) -> str:
    """A result.json as identify writes it, reduced to what export reads: ``rotation`` "held"
    (rotation.model null), a RotationModel, or None (no rotational stage)."""
    doc = {"schema": "droneid.identify/2", "config": {"ts": 0.01},
           "targets": {t: {"final": m.to_dict()} for t, m in models.items()}}
    if rotation is not None:
        doc["rotation"] = {"targets": ["wx_dot", "wy_dot", "wz_dot"],
                           "model": None if rotation == "held" else rotation.to_dict()}
        if horizons:
            doc["rotation"]["dt_s"] = 0.009999999999999787
    path = tmp_path / "result.json"
    path.write_text(json.dumps(doc))
    return str(path)


def test_cli_writes_the_vehicle_of_a_result(tmp_path, capsys):
    log, u, ref = _reference(_rotation())
    result = _result(tmp_path, _translation(), _rotation())
    out = tmp_path / "vehicle.py"
    assert main(["export", result, "--vehicle", "--to", "python", "-o", str(out)]) == 0
    text = out.read_text()
    assert "dt = 0.01 s (the training logs' step the rotational model was fitted at (rotation.dt_s)" in text and "result.json" in text
    np.testing.assert_allclose(_python_rollout(text, log, u), ref, rtol=1e-9, atol=1e-9)
    held = _result(tmp_path, _translation(), "held", horizons=False)
    capsys.readouterr()
    assert main(["export", held, "--vehicle", "--to", "c", "--dt", "0.01"]) == 2   # nothing answers the motors
    err = capsys.readouterr().err
    assert "does not answer the motors on roll, pitch, yaw" in err and "--allow-unsteerable" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert main(["export", held, "--vehicle", "--allow-unsteerable", "--to", "c", "--dt", "0.01"]) == 0
    text = capsys.readouterr().out
    assert "NOT STEERABLE on roll, pitch, yaw" in text
    assert "every body rate is held" in text and "dx[10] = dx[11] = dx[12] = 0.0;" in text
    assert "Step: dt = 0.01 s (given by --dt)" in text
    assert main(["export", held, "--to", "c", "--dt", "0.01"]) == 2           # the equations hold no step
    assert "--dt applies to --vehicle only" in capsys.readouterr().err


def test_every_refusal_of_the_vehicle_is_said_at_once(tmp_path, capsys):
    """A user met the verdict's refusal, passed --identified, then met the steerability's
    (walkthrough): both are said in the one line, each with the option that overrides it."""
    path = _result(tmp_path, _translation(), "held")
    doc = json.loads(Path(path).read_text())
    doc["targets"]["vz_dot"].update(use="empirical", verdict="vz_dot: keep the empirical model")
    Path(path).write_text(json.dumps(doc))
    assert main(["export", path, "--vehicle", "--to", "python"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "(1) identify's verdict does not keep the identified model of vz_dot" in err
    assert "--identified exports it anyway. (2) the identified rotational model does not answer the motors" in err
    assert "--allow-unsteerable" in err and "replay of logged motor speeds" in err


@pytest.mark.parametrize("case, expect", [
    ("no rotation", "result.json: no rotational stage in the result"),
    ("no vz_dot", "result.json: --vehicle needs the final models of vx_dot, vy_dot and vz_dot; the result has "
                  "none of vz_dot"),
    ("no step", "result.json: the result records no step for its rotational model (rotation.dt_s): pass --dt"),
    ("latex", "--vehicle writes python or c, not latex"),
    ("negative delay", "result.json: cannot export the vehicle: the vx_dot model reads rpm1 0.01 s ahead"),
])
def test_cli_refuses_with_one_line(tmp_path, capsys, case, expect):
    models = _translation()
    rotation, horizons, to = "held", True, "python"
    if case == "no rotation":
        rotation = None
    elif case == "no vz_dot":
        models.pop("vz_dot")
    elif case == "no step":
        horizons = False
    elif case == "latex":
        to = "latex"
    else:
        models["vx_dot"] = IdentifiedModel("vx_dot", models["vx_dot"].expr, {"rpm1": -0.01})
    assert main(["export", _result(tmp_path, models, rotation, horizons), "--vehicle", "--allow-unsteerable",
                 "--to", to]) == 2
    err = capsys.readouterr().err.strip()
    assert expect in err and len(err.splitlines()) == 1 and "Traceback" not in err, err


def test_an_unsteerable_vehicle_points_to_the_vehicles_torque_gains(tmp_path, capsys):
    """The exported vehicle cannot be steered, but identify measured the torque gains: the refusal
    and the header give them (with whether they hold across flights) for a controller of one's own."""
    from droneid.rotation.gains import TorqueGains
    path = _result(tmp_path, _translation(), "held")
    doc = json.loads(Path(path).read_text())
    doc["rotation"]["torque_gains"] = TorqueGains(
        "rad/s² per unit of (P s)", ("damping",), {"roll": (52.7, 47.3, 58.7), "pitch": (47.0, 42.0, 54.4),
                                                   "yaw": (3.68, 1.89, 7.11)},
        {"roll": (51.8, 53.5), "pitch": (45.6, 48.0), "yaw": (2.9, 4.6)}).to_dict()
    Path(path).write_text(json.dumps(doc))
    assert main(["export", path, "--vehicle", "--to", "python"]) == 2
    err = capsys.readouterr().err
    assert "torque gains for a controller design of your own" in err and "roll 52.7 [47.3, 58.7]" in err
    assert len(err.strip().splitlines()) == 1
    assert main(["export", path, "--vehicle", "--allow-unsteerable", "--to", "python"]) == 0
    text = capsys.readouterr().out
    assert "The vehicle's torque gains for a controller design of your own" in text
    assert "untested across flights" in text
