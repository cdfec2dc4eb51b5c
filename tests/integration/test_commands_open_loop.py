"""Command-driven vehicles open loop and exported (issue 36 item 5): ``predict --open-loop`` and
``export --vehicle`` drive identify's v̇ models from the logged motor commands and battery voltage
through the identified motor model (thrust curve, battery compensation, motor lag;
:mod:`droneid.simulation.motor_model`).

Planted truth: the lag's step response is the first-order one in closed form; an exported vehicle
(Python, and C compiled strictly) reproduces droneid's own open-loop rollout of a planted command
model to 1e-9; on a simulated command-driven vehicle (motor lag, sagging battery, no rotor speeds
logged) identify's models beat the nominal physics row open loop from the CLI, with no warning."""
from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
import sympy as sp

from droneid.core.expressions import symbol
from droneid.errors import DataError
from droneid.fitting.closed_form import IdentifiedModel
from droneid.simulation.motor_model import MotorModel
from droneid.simulation.openloop import IdentifiedTranslation, StateLog, simulate
from droneid.use.vehicle_export import export_vehicle
from priors.thrust import thrust_columns, thrust_curve

from export_helpers import CC, vehicle_c_rollout, vehicle_python_rollout

DT = 0.01
N, START, H = 240, 180, 50
SPIN = (0.1, 0.95)
V_REF = 12.6


def test_the_lag_is_the_first_order_step_response_of_the_rotor_speed():
    """A command step: the rotor speed w approaches w* = sqrt(f_e(q)) as w* + (w0 − w*)·a^k, the
    models see the command whose curve gives the mean w² over each step, and at rest the command
    itself (battery compensation included)."""
    e, tau = 0.5, 0.05
    m = MotorModel(e, SPIN, V_REF, tau)
    u = np.full((200, 2), 0.4)       # 190 steps after the step: e^-38 of it left
    u[10:] = 0.7
    volts = np.full(200, 0.8 * V_REF)
    eff = m.effective(u, volts, DT)
    q = lambda c: (c - SPIN[0]) / (SPIN[1] - SPIN[0]) * 0.8   # noqa: E731
    w0, w1 = math.sqrt(thrust_curve(q(0.4), e)), math.sqrt(thrust_curve(q(0.7), e))
    a, c = math.exp(-DT / tau), tau / DT * (1 - math.exp(-DT / tau))
    for k in range(10, 200):
        start = w1 + (w0 - w1) * a ** (k - 10)              # the speed at the step's start
        mean = w1 + (start - w1) * c                         # its mean over the step
        assert thrust_curve(q(eff[k, 0]), e) == pytest.approx(mean ** 2, rel=1e-9)
    np.testing.assert_allclose(eff[:10], 0.4, rtol=1e-12)    # at rest: the command itself
    assert 0.4 < eff[10, 0] < 0.55 and eff[-1, 0] == pytest.approx(0.7, rel=1e-6)
    np.testing.assert_array_equal(MotorModel(e, SPIN, V_REF, 0.0).effective(u, volts, DT), u)   # no lag


def _models(delays: dict) -> dict:
    """v̇ of identify's form on the commands: thrust through the curve (spin range, battery
    compensation) along the tilted body z, linear drag, g fixed, an evolved term in motor2."""
    vx, vy, vz, roll, pitch, yaw = (symbol(n) for n in ("vx", "vy", "vz", "roll", "pitch", "yaw"))
    (_, curve, _), = thrust_columns("motor", 4, expo=0.45, v_ref=V_REF, spin=SPIN)
    thrust = 4.9 * curve
    return {"vx_dot": IdentifiedModel("vx_dot", -0.2 * vx + (sp.sin(pitch) * sp.cos(roll) * sp.cos(yaw)
                                                             + sp.sin(roll) * sp.sin(yaw)) * thrust, delays),
            "vy_dot": IdentifiedModel("vy_dot", -0.2 * vy + (sp.sin(pitch) * sp.sin(yaw) * sp.cos(roll)
                                                             - sp.sin(roll) * sp.cos(yaw)) * thrust, delays),
            "vz_dot": IdentifiedModel("vz_dot", -0.4 * vz + sp.cos(pitch) * sp.cos(roll) * thrust
                                      + 0.3 * symbol("motor2") ** 2 - 9.81, delays)}


def _log() -> StateLog:
    """Commands near hover (random walk), a battery sagging 12.4 -> 11.0 V, a tilted moving state."""
    rng = np.random.default_rng(5)
    cmds = 0.55 + np.cumsum(rng.normal(0.0, 0.01, (N, 4)), axis=0)
    volts = np.linspace(12.4, 11.0, N) + rng.normal(0.0, 0.02, N)
    state = np.zeros((N, 13))
    q = np.array([np.cos(0.2), 0.05, -0.03, np.sin(0.2)])
    state[:] = np.concatenate([[0.1, -0.2, 1.0, 0.6, -0.4, 0.1], q / np.linalg.norm(q), [0.3, -0.2, 0.4]])
    signals = {f"motor{i + 1}": cmds[:, i] for i in range(4)}
    signals["battery_voltage"] = volts
    return StateLog("synthetic", DT * np.arange(N), state, np.zeros((N, 0)), DT, signals)


def _logged(log: StateLog) -> np.ndarray:
    """The inputs an exported command vehicle is fed per step: the commands, then the voltage."""
    return np.column_stack([log.signals[n] for n in ("motor1", "motor2", "motor3", "motor4", "battery_voltage")])


CASES = {"lag": ({"motor1": 0.03, "motor2": 0.03, "motor3": 0.03, "motor4": 0.03, "battery_voltage": 0.03}, 0.04),
         "offset": ({"motor1": 0.03, "motor2": 0.02, "motor3": 0.03, "motor4": 0.04}, 0.0)}


@pytest.mark.parametrize("case", CASES)
def test_exported_command_vehicle_reproduces_the_open_loop_rollout(tmp_path, case):
    delays, tau = CASES[case]
    motor = MotorModel(0.45, SPIN, V_REF, tau)
    tr = IdentifiedTranslation(_models(delays), motor)
    log = _log()
    u = tr.inputs(log)
    ref = simulate(tr, log.state[START][None], u[None, START:START + H], DT)[0]
    text = export_vehicle(_models(delays), None, "python", dt_s=DT, motor=motor)
    got = vehicle_python_rollout(text, _logged(log), log.state[START], START, H, u)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)
    assert np.ptp(ref[:, 3:6], axis=0).max() > 0.05                     # the velocity changed
    for must in ("stepped open loop from motor commands", "inputs[5]: motor1 (1)", "battery_voltage (V)",
                 f"EXPO = 0.45", "SPIN_LO = 0.1, SPIN_HI = 0.95", "V_REF = 12.6 V"):
        assert must in text, must
    if tau:
        assert "TAU = 0.04 s" in text and "read at t, not at the models' offsets" in text
        assert "motor1 of 0 step(s) earlier" in text
        # the models' own offsets (their docstrings, the header) say the vehicle feeds them otherwise
        assert "feed motor4 at t - 0.03 s (called on their own; in this vehicle the commands are read at t" in text
        assert text.count("in this vehicle the commands are read at t through the motor lag") >= 6
        # the lag answers a command step over its time constant, not at once
        step = _logged(log).copy()
        step[START:, :4] += 0.1
        moved = vehicle_python_rollout(text, step, log.state[START], START, H)
        assert np.abs(moved[0, 3:6] - got[0, 3:6]).max() < np.abs(moved[H // 2, 3:6] - got[H // 2, 3:6]).max()
    else:
        assert "No motor lag was kept" in text and "motor4 of 4 step(s) earlier" in text
        assert "in this vehicle" not in text
    if CC is not None:
        c = vehicle_c_rollout(tmp_path, export_vehicle(_models(delays), None, "c", dt_s=DT, motor=motor),
                              _logged(log), log.state[START], START, H)
        np.testing.assert_allclose(c, ref, rtol=1e-9, atol=1e-9)


def test_commands_without_a_motor_model_are_refused():
    with pytest.raises(DataError, match="motor model"):
        IdentifiedTranslation(_models({}))


@pytest.mark.slow
def test_simulated_command_vehicle_beats_nominal_physics_from_the_cli(tmp_path, capsys):
    """identify (the physical model, a token SNGP budget) on three training flights of a vehicle with
    a 50 ms motor lag and a sagging battery, rotor speeds removed; ``predict --open-loop`` on a fourth
    flight: the identified row's velocity and position SimErr below nominal physics (the prior's own
    command law, no drag, no lag); ``export --vehicle`` writes it; no Python warning on the way."""
    from droneid import Identifier
    from droneid.cli import main
    from droneid.simulation.simulator import simulate as fly
    from parsers.csv_writer import write_flat_csv

    def flight(path, seed):
        return fly(path=path, duration_s=25.0, seed=seed, thrust_expo=0.5, motor_tau_s=0.05,
                   effects={"thrust_variation": {"amp_m": 0.5, "period_s": 3.0 + seed % 3},
                            "battery_sag": {"v_start": 12.6, "v_end": 9.9, "exponent": 2.0}}
                   ).flight.without("rpm1", "rpm2", "rpm3", "rpm4")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        train = [flight(p, s) for s, p in enumerate(("random", "eight", "lissajous"))]
        res = Identifier(effects="none", rotation="none", runs=1, generations=50, population_size=40,
                         jobs=1).fit(train)
        assert res.plan.thrust_curve["lag_s"] > 0            # identify kept a motor lag
        result = tmp_path / "result.json"
        result.write_text(json.dumps(res.to_dict()))
        log = write_flat_csv(flight("square", 7), tmp_path / "square.csv")
        capsys.readouterr()
        assert main(["predict", str(result), str(log), "--open-loop", "--json"]) == 0
        doc = json.loads(capsys.readouterr().out)
        assert main(["export", str(result), "--vehicle", "--allow-unsteerable", "--to", "python",
                     "-o", str(tmp_path / "vehicle.py")]) == 0
    ol = doc["open_loop"]
    assert list(ol) == ["identified", "nominal physics", "constant"]
    for q in ("velocity", "position"):
        assert ol["identified"]["simerr"][q] < ol["nominal physics"]["simerr"][q] < ol["constant"]["simerr"][q], q
    assert "lags" in doc["open_loop_inputs"]
    assert "inputs.push(logged)" in (tmp_path / "vehicle.py").read_text()


# -- the rotational model on commands (issue 36 item 5) ---------------------------------------------
def _command_rotation(case: str):
    """A planted command-driven rotational model: torque from the rotors' normalised thrust
    differences, centre, decay and yaw spin-up, with the conditioning identify may choose (rotor
    delay, low-pass, running balance), its rotor speeds from the commands through the motor model
    (the lag, or the offset without one)."""
    from priors.torque import get_layout
    from droneid.rotation.commands import CommandSpeeds
    from droneid.rotation.model import SPEED_UNIT, RotationModel
    delays, tau = CASES[case]
    speeds = CommandSpeeds(MotorModel(0.45, SPIN, V_REF, tau), 4, 0.0 if tau else delays["motor1"])
    coef = (np.array([40.0, 1.5, 3.0]), np.array([35.0, -2.0, 4.0]), np.array([6.0, 0.5, 1.0, 0.02]))
    return RotationModel(get_layout("quad_x"), ("centre", "damping", "spinup"), coef, np.array([0.1, -0.2, 0.05]),
                         delay_steps=2, rad_s_per_rpm=SPEED_UNIT, lowpass_tau_s=0.03, balance_weight_s=1.0,
                         balance_prior=np.full(4, 0.3), commands=speeds)


def test_command_rotation_reads_the_rotors_thrust_fractions():
    """The rotational model's s_i are f_e(q_i) of the commands (at rest: no lag transient), in units of
    full thrust, and a command held constant gives a constant speed through the lag."""
    rot = _command_rotation("offset")
    log = _log()
    w = rot.commands.speeds(log)
    k = rot.commands.offset_steps(DT)
    assert k == 3
    q = (log.signals["motor2"][100 - k] - SPIN[0]) / (SPIN[1] - SPIN[0]) * log.signals["battery_voltage"][100 - k] / V_REF
    assert w[100, 1] ** 2 == pytest.approx(thrust_curve(q, 0.45), rel=1e-12)
    lagged = _command_rotation("lag").commands
    held = replace_signals(log, {f"motor{i}": np.full(N, 0.6) for i in range(1, 5)} | {"battery_voltage": np.full(N, V_REF)})
    np.testing.assert_allclose(lagged.speeds(held), math.sqrt(thrust_curve((0.6 - SPIN[0]) / (SPIN[1] - SPIN[0]), 0.45)),
                               rtol=1e-12)


def replace_signals(log: StateLog, signals: dict) -> StateLog:
    from dataclasses import replace
    return replace(log, signals=signals)


@pytest.mark.parametrize("case", CASES)
def test_exported_command_vehicle_with_rotation_reproduces_the_open_loop_rollout(tmp_path, case):
    """export --vehicle of a command-driven vehicle WITH a rotational model: the file (Python, C)
    steps the body rates from the commands as droneid's own open loop (IdentifiedVehicle) does,
    to 1e-9, and its header says which axes answer the motors."""
    from droneid.simulation.openloop import IdentifiedVehicle
    delays, tau = CASES[case]
    motor = MotorModel(0.45, SPIN, V_REF, tau)
    rot = _command_rotation(case)
    vehicle = IdentifiedVehicle(IdentifiedTranslation(_models(delays), motor), rot)
    log = _log()
    u = vehicle.inputs(log)
    ref = simulate(vehicle, log.state[START][None], u[None, START:START + H], DT)[0]
    assert np.ptp(ref[:, 10:13], axis=0).min() > 0.05          # every body rate moved
    text = export_vehicle(_models(delays), rot, "python", dt_s=DT, motor=motor)
    got = vehicle_python_rollout(text, _logged(log), log.state[START], START, H, u)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)
    assert "Body axes that answer the motors (a torque term): roll, pitch, yaw." in text
    assert "thrust as a fraction of full thrust" in text
    if CC is not None:
        c = vehicle_c_rollout(tmp_path, export_vehicle(_models(delays), rot, "c", dt_s=DT, motor=motor),
                              _logged(log), log.state[START], START, H)
        np.testing.assert_allclose(c, ref, rtol=1e-9, atol=1e-9)


@pytest.mark.slow
def test_simulated_command_vehicle_rotation_from_the_cli(tmp_path, capsys):
    """identify on three simulated command-driven flights (no rotor speeds) reaches the rotational
    stage through the motor model; ``predict --open-loop`` flies the identified rotational model
    from the commands (its body-rate error is not the rates-held one when an axis left ``held``);
    ``export --vehicle`` refuses an axis that does not answer the motors unless
    ``--allow-unsteerable``, and its header says which axes answer them."""
    from droneid import Identifier
    from droneid.cli import main
    from droneid.simulation.simulator import simulate as fly
    from droneid.use.predict import models_from_document, open_loop_section
    from parsers.csv_writer import write_flat_csv

    def flight(path, seed):
        return fly(path=path, duration_s=20.0, seed=seed, thrust_expo=0.5, motor_tau_s=0.04,
                   effects={"thrust_variation": {"amp_m": 0.5, "period_s": 3.0 + seed % 3}}
                   ).flight.without("rpm1", "rpm2", "rpm3", "rpm4")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        train = [flight(p, s) for s, p in enumerate(("random", "eight", "lissajous"))]
        test = flight("square", 7)
        res = Identifier(effects="none", frame="quad_x", runs=1, generations=50, population_size=40,
                         jobs=1).fit(train, test=[test])
        rot = res.rotation
        assert rot is not None and rot.from_commands, res.notes
        # scored on the test flight, held axes included (through the plan's motor model)
        assert all(math.isfinite(a.test_held) and math.isfinite(a.test_model) for a in rot.axes), rot.notes
        assert not any("not scored" in n for n in rot.notes)
        doc = res.to_dict()
        result = tmp_path / "result.json"
        result.write_text(json.dumps(doc))
        log = write_flat_csv(test, tmp_path / "square.csv")
        capsys.readouterr()
        assert main(["predict", str(result), str(log), "--open-loop", "--json"]) == 0
        ol = json.loads(capsys.readouterr().out)["open_loop"]
        models = models_from_document(doc)
        held = open_loop_section({**models, "_rotation": None}, [test])["identified"]["simerr"]["rates"]
        moved = [a.target for a in rot.axes if a.rung != "held"]
        if moved:
            assert ol["identified"]["simerr"]["rates"] != pytest.approx(held, rel=1e-6)
        else:
            assert ol["identified"]["simerr"]["rates"] == pytest.approx(held, rel=1e-9)
        out = tmp_path / "vehicle.py"
        stuck = [a for a in rot.axes if "does not respond to the motors" in a.verdict]
        code = main(["export", str(result), "--vehicle", "--to", "python", "-o", str(out)])
        assert code == (2 if stuck else 0)
        assert main(["export", str(result), "--vehicle", "--to", "python", "--allow-unsteerable", "-o", str(out)]) == 0
    text = out.read_text()
    assert "Body axes that answer the motors" in text
    assert ("thrust as a fraction of full thrust" in text) == (rot.model is not None)
