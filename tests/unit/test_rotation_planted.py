"""The rotational model of droneid.rotation.model against planted truth (issue 28): the simulator's rigid
body (torques from rotor thrust differences through the layout, yaw from the rotor drag torques,
the gyroscopic ω × Jω), a planted rotor drag moment with a balance point of its own per flight,
the choice by blocked validation, and the whole vehicle stepped by openloop.IdentifiedVehicle."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.simulation.openloop import IdentifiedVehicle, StateLog, open_loop, simulate, state_log
from droneid.rotation.model import RotationModel, TranslationModel, balanced, fit_rotation, fit_translation
from droneid.rotation.choice import select_rotation
from droneid.simulation.simulator import simulate as simulate_flight
from priors.torque import get_layout
from test_rotation import _smooth_noise   # smooth random motor speeds, shared with the older rotation tests

DT = 0.01
TRANSLATION = TranslationModel(k_thrust=0.83, drag=np.array([0.3, 0.2, 0.1]))
#: planted per axis: [pattern, damping, rotor drag] (roll, pitch), [pattern, damping] (yaw)
DRAG_COEF = (np.array([6.0, 3.0, 2.0]), np.array([5.0, 3.0, 1.5]), np.array([1.5, 3.0]))
DRAG_TERMS = ("damping", "rotor_drag")
LAYOUT = get_layout("crazyflie_x")


def _balanced_flight(seed, offset, n=1500, name=None):
    """A flight from the planted model whose balance point is its own: its motor speeds carry the
    per-rotor offset ``offset`` (rpm) and the planted trim cancels exactly the torque of that
    offset's mean ``s`` (a centre of gravity that the controller trims out)."""
    rng = np.random.default_rng(seed)
    rpm = 95000.0 + np.asarray(offset, float) + _smooth_noise(rng, n, 4, 2500.0)
    shell = RotationModel(LAYOUT, DRAG_TERMS, DRAG_COEF, np.zeros(3))
    s_mean = shell.conditioned(rpm, DT)[0].mean(axis=0)
    trim = -np.array([DRAG_COEF[k][0] * (LAYOUT.patterns()[k] @ s_mean) for k in range(3)])
    truth = IdentifiedVehicle(TRANSLATION, RotationModel(LAYOUT, DRAG_TERMS, DRAG_COEF, trim))
    dummy = StateLog(name or f"flight{seed}", DT * np.arange(n), np.zeros((n, 13)), rpm, DT)
    x0 = np.array([0, 0, 100.0, 0.5, -0.3, 0, 1, 0, 0, 0, 0.2, -0.1, 0.0])
    states = np.vstack([x0, simulate(truth, x0[None], truth.inputs(dummy)[None, :-1], DT)[0]])
    return StateLog(dummy.name, dummy.t_s, states, rpm, DT)


@pytest.fixture(scope="module")
def drag_flights():
    offsets = ([300.0, -300.0, 300.0, -300.0], [-400.0, 200.0, -100.0, 300.0], [600.0, -200.0, -600.0, 200.0])
    return [_balanced_flight(seed, off) for seed, off in zip((11, 12, 13), offsets)]


def test_simulator_rigid_body_is_recovered_from_rotor_speeds():
    """droneid.simulation.simulator flies a closed-loop quad whose rotors deliver ``J ω̇ + ω × Jω``: the fit
    finds k_f·arm/J per axis, k_f·k_m/J_z for yaw, the inertia ratios of the gyroscopic term, and
    no damping or rotor drag moment (the simulator has none)."""
    runs = [simulate_flight(path=p, duration_s=20, seed=s, noise=False) for p, s in (("random", 1), ("lissajous", 2))]
    P = runs[0].truth["params"]
    m = fit_rotation([state_log(r.flight) for r in runs], "quad_x", rad_s_per_rpm=1.0,
                     terms=("centre", "damping", "gyro", "rotor_drag"))
    J = np.array([P["inertia_xx"], P["inertia_yy"], P["inertia_zz"]])
    scale = P["k_f"] * 1e6   # s is (rpm / 1000)²
    gain = [scale * P["arm_m"] / J[0], scale * P["arm_m"] / J[1], scale * P["yaw_moment_m"] / J[2]]
    gyro = [(J[1] - J[2]) / J[0], (J[2] - J[0]) / J[1], (J[0] - J[1]) / J[2]]
    for k in range(3):   # columns: pattern, centre, damping, gyro, (rotor drag on roll and pitch)
        assert m.coef[k][0] == pytest.approx(gain[k], rel=0.03), k
        assert m.coef[k][3] == pytest.approx(gyro[k], rel=0.05), k
        assert abs(m.coef[k][2]) < 0.05, k                      # damping (1/s): none planted
    assert abs(m.coef[0][4]) < 0.01 and abs(m.coef[1][4]) < 0.01  # rotor drag: none planted


def test_balanced_is_causal_and_tends_to_the_flight_mean():
    rng = np.random.default_rng(3)
    s = np.array([2.0, 2.1, 1.9, 2.0]) + 0.1 * rng.standard_normal((3000, 4))
    b = balanced(s, DT, prior=np.full(4, 2.0), weight_s=1.0)
    np.testing.assert_allclose(b[0], s[0] - (s[0] * DT + 2.0 * 1.0) / (DT + 1.0))   # one step plus 1 s of prior
    np.testing.assert_allclose(b[-1000:].mean(axis=0), 0.0, atol=0.01)
    later = s.copy()
    later[2000:] += 3.0
    np.testing.assert_array_equal(balanced(later, DT, None, 1.0)[:2000], balanced(s, DT, None, 1.0)[:2000])
    assert balanced(s, DT, None, None) is s


@pytest.mark.slow   # shares a ~10 s simulated-flight fixture
def test_rotor_drag_moment_and_damping_are_recovered(drag_flights):
    """One trim per training flight (as planted): the coefficients come back."""
    m = fit_rotation(drag_flights, terms=DRAG_TERMS)
    for k in range(3):
        np.testing.assert_allclose(m.coef[k], DRAG_COEF[k], rtol=0.05)


@pytest.mark.slow   # shares a ~10 s simulated-flight fixture
def test_a_new_flights_balance_point_is_found_from_its_own_motor_speeds(drag_flights):
    """Fitted on two flights, the third (another balance point) is predicted open loop with at
    least a third less body-rate error with the balance than with the training flights' mean trim
    (the balance is not exact: it starts from the training mean and learns the flight's own as the
    flight goes on)."""
    train, new = drag_flights[:2], drag_flights[2:]
    tr = fit_translation(train)
    with_balance = fit_rotation(train, terms=DRAG_TERMS, balance_weight_s=1.0)
    mean_trim = fit_rotation(train, terms=DRAG_TERMS)
    res = open_loop({"balance": IdentifiedVehicle(tr, with_balance),
                     "mean trim": IdentifiedVehicle(tr, mean_trim)}, new, stride=10)
    assert res["balance"].simerr["rates"] < 2.0 / 3.0 * res["mean trim"].simerr["rates"]


@pytest.mark.slow   # shares a ~10 s simulated-flight fixture
def test_selection_keeps_the_planted_structure(drag_flights):
    """Three training flights, 12 (flight, regime) cells per step: enough for the sign-flip test to
    pass Holm's thresholds at α = 0.01 (p ≥ 2^-12 against 0.01/7 for the first); every axis
    climbs to the planted torque model, which beats the decay below it in every cell."""
    cands = [{"terms": ("damping",), "balance_weight_s": 1.0},
             {"terms": DRAG_TERMS, "balance_weight_s": 1.0}]
    choice = select_rotation(drag_flights, candidates=cands, translation_delay_steps=0, stride=10)
    assert choice.axis_choice == ("torque", "torque", "torque") and choice.beats_held
    assert choice.table[1]["rates_simerr"] < choice.table[0]["rates_simerr"] < choice.held["rates_simerr"]
    row = choice.table[choice.chosen]
    assert row["method"] == "per-axis" and row["torque_candidate"] == 1
    # per body axis (each rotational target's verdict against the rates held)
    assert all(m < h for m, h in zip(row["rates_axis_simerr"], choice.held["rates_axis_simerr"]))
    for k in range(3):   # the refitted model is the planted one on every axis
        got = dict(zip(choice.model.columns(k), choice.model.coef[k]))
        assert got["pattern"] == pytest.approx(DRAG_COEF[k][0], rel=0.05), k
    assert [step["flights"] for step in choice.ladder] == [[f.name for f in drag_flights]] * 3
    import json
    back = json.loads(json.dumps(choice.to_dict()))
    assert back["axis_choice"] == ["torque"] * 3 and back["chosen"] == choice.chosen
    top = back["ladder"][0]["steps"][-1]
    assert top["taken"] and len(top["ratio"]) == 4 and top["cells"] == 12
    assert top["p_value"] < top["threshold"] and back["ladder"][0]["family_size"] == 7
    # two of the flights: 8 cells cannot reach 0.01/7 (p ≥ 2^-8), so every rate is held
    two = select_rotation(drag_flights[:2], candidates=cands[1:], translation_delay_steps=0, stride=10)
    assert two.model is None and two.axis_choice == ("held", "held", "held")
    assert all(st["p_value"] >= 2.0 ** -8 and not st["taken"] for st in two.ladder[0]["steps"])


def test_selection_holds_the_rates_when_no_model_beats_holding_them():
    """Body rates that never change: holding them is exact, so no fitted model is kept."""
    logs = []
    for seed in (1, 2):
        rng = np.random.default_rng(seed)
        n = 600
        rpm = 95000.0 + _smooth_noise(rng, n, 4, 2500.0)
        state = np.zeros((n, 13))
        state[:, 2] = 1.0
        state[:, 6] = 1.0
        state[:, 10:13] = [0.1 * seed, -0.05, 0.02]
        logs.append(StateLog(f"still{seed}", DT * np.arange(n), state, rpm, DT))
    choice = select_rotation(logs, candidates=[{"terms": ("damping",)}], translation_delay_steps=0, stride=10)
    assert choice.model is None and not choice.beats_held and choice.chosen is None
    assert choice.held["rates_simerr"] == 0.0


def test_identified_vehicle_steps_both_halves_with_a_unit_quaternion():
    rng = np.random.default_rng(5)
    rot = RotationModel(LAYOUT, DRAG_TERMS, DRAG_COEF, np.array([0.1, -0.2, 0.05]))
    veh = IdentifiedVehicle(TRANSLATION, rot)
    n = 60
    rpm = 95000.0 + _smooth_noise(rng, n, 4, 2500.0)
    log = StateLog("x", DT * np.arange(n), np.zeros((n, 13)), rpm, DT)
    u = veh.inputs(log)
    assert u.shape == (n, 4 + rot.input_width)
    np.testing.assert_array_equal(u[:, :4], TRANSLATION.inputs(log))
    np.testing.assert_array_equal(u[:, 4:], rot.inputs(log))
    x = np.array([[0, 0, 1.0, 1.0, 0.5, 0, np.cos(0.2), np.sin(0.2), 0, 0, 0.5, -0.4, 0.3]])
    np.testing.assert_allclose(veh.accel(x, u[:1]), TRANSLATION.accel(x, u[:1, :4]))
    np.testing.assert_allclose(veh.ang_accel(x, u[:1]), rot.ang_accel(x, u[:1, 4:]))
    out = simulate(veh, x, u[None, :50], DT)[0]
    np.testing.assert_allclose(np.linalg.norm(out[:, 6:10], axis=1), 1.0, atol=1e-12)
    assert np.ptp(out[:, 10:13], axis=0).min() > 0.01      # the rates move: ω̇ is not zero


def test_column_names_follow_the_coefficients():
    rot = RotationModel(LAYOUT, ("centre", "damping", "gyro", "spinup", "rotor_drag"), DRAG_COEF, np.zeros(3))
    assert rot.columns(0) == ("pattern", "centre", "damping", "gyro", "rotor_drag")
    assert rot.columns(2) == ("pattern", "centre", "damping", "gyro", "spinup")


@pytest.mark.slow   # shares a ~10 s simulated-flight fixture
def test_multistep_fit_recovers_the_rotor_drag_moment(drag_flights):
    from droneid.rotation.choice import fit_rotation_multistep
    m = fit_rotation_multistep(drag_flights, rotor_drag=True, spinup=False, damping_grid=(2.0, 3.0, 4.0), stride=10)
    for k in range(3):
        got = dict(zip(m.columns(k), m.coef[k]))
        assert got["pattern"] == pytest.approx(DRAG_COEF[k][0], rel=0.05), k
        assert got["damping"] == 3.0, k
        assert abs(got["centre"]) < 0.02, k               # none planted
        if k < 2:
            assert got["rotor_drag"] == pytest.approx(DRAG_COEF[k][2], rel=0.05), k


def test_models_round_trip_through_json():
    import json
    rot = RotationModel(LAYOUT, ("centre", "damping", "rotor_drag"), (np.array([6.0, 0.1, 3.0, 2.0]),
                        np.array([5.0, 0.0, 3.0, 1.5]), np.array([1.5, 0.0, 3.0])), np.array([0.1, -0.2, 0.0]),
                        delay_steps=1, lowpass_tau_s=0.05, balance_weight_s=1.0, balance_prior=np.full(4, 2.5))
    back = RotationModel.from_dict(json.loads(json.dumps(rot.to_dict())))
    x = np.array([[0, 0, 1.0, 1.0, -0.5, 0, 1, 0, 0, 0, 0.3, -0.2, 0.1]])
    rng = np.random.default_rng(2)
    log = StateLog("x", DT * np.arange(50), np.zeros((50, 13)), 95000.0 + 500 * rng.standard_normal((50, 4)), DT)
    np.testing.assert_array_equal(back.inputs(log), rot.inputs(log))
    np.testing.assert_array_equal(back.ang_accel(x, rot.inputs(log)[:1]), rot.ang_accel(x, rot.inputs(log)[:1]))
    assert back.columns(0) == rot.columns(0)
    tr = TranslationModel.from_dict(json.loads(json.dumps(TRANSLATION.to_dict())))
    np.testing.assert_array_equal(tr.accel(x, TRANSLATION.inputs(log)[:1]), TRANSLATION.accel(x, TRANSLATION.inputs(log)[:1]))
    from droneid.errors import DataError
    with pytest.raises(DataError, match="damaged"):
        RotationModel.from_dict({"terms": []})
