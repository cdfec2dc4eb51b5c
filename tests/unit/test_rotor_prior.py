"""The rotor-thrust prior, its constraints and the automatic prior choice."""
import numpy as np
import pytest

from droneid.errors import ConfigError
from droneid.core.frames import euler_to_matrix
from droneid.fitting.closed_form import IdentifiedModel
from priors.constraints import rotor_thrust as rotor_constraints
from priors.registry import choose_prior, get_prior


def _columns(n=200, seed=0):
    rng = np.random.default_rng(seed)
    cols = {"roll": rng.uniform(-0.6, 0.6, n), "pitch": rng.uniform(-0.6, 0.6, n),
            "yaw": rng.uniform(-3, 3, n), "vx": rng.normal(0, 1, n), "vy": rng.normal(0, 1, n),
            "vz": rng.normal(0, 0.5, n)}
    for i in range(1, 5):
        cols[f"rpm{i}"] = rng.uniform(8000, 20000, n)
    return cols


def test_rotor_thrust_is_thrust_along_the_rotated_body_z_minus_gravity_and_drag():
    """Checked against droneid.core.frames' own rotation matrix (independent code)."""
    k_T, k_D, g = 1.09, 0.28, 9.81
    prior = get_prior("rotor-thrust", source="rpm", motors=4, k_T=k_T, k_D=k_D)
    cols = _columns()
    R = np.array([euler_to_matrix(r, p, y) for r, p, y in zip(cols["roll"], cols["pitch"], cols["yaw"])])
    thrust = k_T * sum((cols[f"rpm{i}"] / 1e4) ** 2 for i in range(1, 5))
    expected = thrust[:, None] * R[:, :, 2] - np.array([0, 0, g]) - k_D * np.column_stack(
        [cols["vx"], cols["vy"], cols["vz"]])
    for j, t in enumerate(("vx_dot", "vy_dot", "vz_dot")):
        got = prior.evaluate(cols, t, 1)[:, 0]
        assert np.allclose(got, expected[:, j], rtol=1e-10, atol=1e-9), t
        split = prior.evaluate(cols, t)
        assert np.allclose(split.sum(axis=1), got)
        assert [f.role for f in prior.features(t)][0] == "thrust"


def test_rotor_thrust_as_given_meets_its_own_constraints():
    prior = get_prior("rotor-thrust", source="rpm", motors=4)
    for t in ("vx_dot", "vy_dot", "vz_dot"):
        cs = rotor_constraints(t, {f"rpm{i}": 20000.0 for i in range(1, 5)})
        samples = cs.sample(list(prior.inputs(t)), n_per_constraint=40, seed=3)
        cols = {n: samples.X[:, i] for i, n in enumerate(samples.input_names)}
        pred = prior.evaluate(cols, t, 1)[:, 0]
        from droneid.core.constraint_samples import constraint_rmse
        assert constraint_rmse(pred, samples) < 1e-9, t


def test_rotor_thrust_sources_and_errors():
    for source, signals in (("motor", {"motor1", "motor2", "motor3", "motor4"}), ("throttle", {"throttle"}),
                            ("thrust", {"thrust"})):
        p = get_prior("rotor-thrust", source=source)
        assert signals <= set(p.inputs("vx_dot"))
        assert p.params["source"] == source
    with pytest.raises(ConfigError, match="unknown thrust source 'rpms'.*rpm"):
        get_prior("rotor-thrust", source="rpms")
    with pytest.raises(ConfigError, match="motors"):
        get_prior("rotor-thrust", motors=0)


def test_auto_prefers_the_most_direct_thrust_signal():
    rpm = [f"rpm{i}" for i in range(1, 5)]
    cmd = [f"motor{i}" for i in range(1, 5)]
    assert choose_prior([*rpm, *cmd, "throttle"])[:2] == ("rotor-thrust", {"source": "rpm", "motors": 4})
    assert choose_prior([*cmd, "throttle"])[:2] == ("rotor-thrust", {"source": "motor", "motors": 4})
    assert choose_prior(["thrust", "throttle"])[:2] == ("rotor-thrust", {"source": "thrust"})
    assert choose_prior(["rpm1", "rpm2", "throttle"])[:2] == ("rotor-thrust", {"source": "throttle"})
    name, params, reason = choose_prior(["vx", "roll"])
    assert name == "tilt-drag" and "no motor speeds" in reason
    assert choose_prior(["vx"], "tilt-drag")[0] == "tilt-drag"
    with pytest.raises(ConfigError, match="rotor-thrust.*needs motor speeds"):
        choose_prior(["vx"], "rotor-thrust")


def test_identified_model_round_trips_through_its_dict():
    prior = get_prior("rotor-thrust")
    expr = sum(f.expr for f in prior.features("vz_dot"))
    m = IdentifiedModel("vz_dot", expr, {"rpm1": 0.04, "rpm2": 0.0}, "test")
    d = m.to_dict()
    assert d["delays_s"] == {"rpm1": 0.04}  # zero delays are dropped
    back = IdentifiedModel.from_dict(d)
    cols = _columns(50)
    assert np.allclose(back.evaluate(cols), m.evaluate(cols), rtol=1e-12)
    assert back.signals == m.signals


@pytest.mark.slow
def test_identify_and_diagnose_choose_the_same_auto_prior_when_motor_speeds_are_too_slow():
    """4 Hz ESC telemetry must not win over 100 Hz motor commands, in either pipeline."""
    from droneid.diagnosis.diagnose import diagnose_plan
    from droneid.logs.flight import Signal
    from droneid.identify.pipeline import IdentifyConfig
    from droneid.planning.plan import resolve_plan_prior
    from droneid.simulation.simulator import simulate
    f = simulate(path="eight", duration_s=10.0, rate_hz=100.0, seed=3).flight
    assert f.has("rpm1", "motor1")
    slow = [Signal(n, f[n].t[::25], f[n].values[::25], f[n].unit) for n in ("rpm1", "rpm2", "rpm3", "rpm4")]
    f = f.with_signals(*slow)
    cfg = IdentifyConfig.make(prior="auto")
    plan_prior, _ = resolve_plan_prior(cfg, [f])
    diag = diagnose_plan([f], "auto")
    assert plan_prior.params["source"] == diag.prior.params["source"] == "motor", diag.prior_reason


def test_a_motor_source_missing_a_rotor_is_passed_over_and_said():
    """A CSV without m3_erpm has rotor speeds 1, 2 and 4: the commands drive the thrust then, and
    the reason says why the speeds were not used; speeds of 4 rotors out of 8 never stand for an
    octocopter's thrust."""
    from priors.registry import choose_prior
    name, params, why = choose_prior({"rpm1", "rpm2", "rpm4", "motor1", "motor2", "motor3", "motor4"})
    assert params == {"source": "motor", "motors": 4}
    assert why.endswith("its motor speeds are incomplete (rpm1, rpm2, rpm4; no rpm3)"), why
    octo = {f"rpm{i}" for i in (1, 2, 3, 4, 6, 7, 8)} | {f"motor{i}" for i in range(1, 9)}
    assert choose_prior(octo)[1] == {"source": "motor", "motors": 8}
    assert choose_prior({f"rpm{i}" for i in range(1, 5)}) == ("rotor-thrust", {"source": "rpm", "motors": 4},
                                                               "the log has 4 motor speeds (rpm1..rpm4)")
