"""Simulator physics against planted truth.

Residuals are "accelerations from the logged velocity (central differences) minus the paper's
tilt-drag model on the logged states"; each effect must move them in the analytically expected
direction and by the expected size.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from droneid.errors import ConfigError
from droneid.simulation.simulator import EFFECTS, PATHS, parse_effects, simulate, tilt_drag_model

G, KD = 9.81, 0.28
RATE = 20.0
DUR = 24.0


def _cols(flight, *names):
    return [flight[n].values for n in names]


def _residual(flight):
    """(rx, ry, t, idx): differentiated logged velocity minus the tilt-drag model (interior samples)."""
    vx, vy, r, p, y = _cols(flight, "vx", "vy", "roll", "pitch", "yaw")
    t = flight["vx"].t
    ax = (vx[2:] - vx[:-2]) / (t[2:] - t[:-2])
    ay = (vy[2:] - vy[:-2]) / (t[2:] - t[:-2])
    mx, my = tilt_drag_model(vx, vy, r, p, y, KD, G)
    return ax - mx[1:-1], ay - my[1:-1], t[1:-1], slice(1, -1)


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _slope(pred, resid):
    """Least-squares slope of resid on pred (no intercept) and their correlation."""
    pred, resid = np.ravel(pred), np.ravel(resid)
    return float(pred @ resid / (pred @ pred)), float(np.corrcoef(pred, resid)[0, 1])


@pytest.fixture(scope="module")
def control():
    return simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3)


@pytest.fixture(scope="module")
def control_clean():
    return simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, noise=False)


# ---------------------------------------------------------------------------------------------
def test_deterministic_from_seed():
    a = simulate(path="random", duration_s=5, rate_hz=RATE, seed=7)
    b = simulate(path="random", duration_s=5, rate_hz=RATE, seed=7)
    c = simulate(path="random", duration_s=5, rate_hz=RATE, seed=8)
    for n in a.flight.names:
        np.testing.assert_array_equal(a.flight[n].values, b.flight[n].values)
    assert a.truth == b.truth
    assert not np.array_equal(a.flight["x"].values, c.flight["x"].values)


def test_flight_contents(control):
    f = control.flight
    expected = {"x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw", "qw", "qx", "qy", "qz",
                "wx", "wy", "wz", "ax", "ay", "az", "throttle", "thrust", "motor1", "motor2",
                "motor3", "motor4", "rpm1", "rpm2", "rpm3", "rpm4", "battery_voltage"}
    assert set(f.names) == expected
    assert f.provenance.format == "simulated"
    assert len(f["x"]) == int(DUR * RATE) + 1
    assert f.segments["in_flight"] == ((0.0, DUR),)
    assert np.allclose(np.diff(f["x"].t), 1 / RATE)
    # the quaternion is the logged Euler angles
    from droneid.core.frames import quat_to_euler
    r, p, y = quat_to_euler(np.column_stack(_cols(f, "qw", "qx", "qy", "qz")))
    np.testing.assert_allclose(r, f["roll"].values, atol=1e-12)
    np.testing.assert_allclose(p, f["pitch"].values, atol=1e-12)
    # the accelerometer's specific force has the size of the true (a + g e3)
    tr = control.truth
    true_norm = np.sqrt(np.square(tr["ax"]) + np.square(tr["ay"]) + np.square(np.add(tr["az"], G)))
    log_norm = np.sqrt(sum(np.square(v) for v in _cols(f, "ax", "ay", "az")))
    np.testing.assert_allclose(log_norm, true_norm, atol=0.25)
    # moderate tilt like the paper's Bebop flights
    tilt = control.truth["model"]["max_tilt_rad"]
    assert 0.15 < tilt < 0.3
    import json
    json.dumps(control.truth, allow_nan=False)


@pytest.mark.parametrize("path", PATHS)
def test_every_path_tracks(path):
    res = simulate(path=path, duration_s=8, rate_hz=RATE, seed=1, noise=False)
    f = res.flight
    z = f["z"].values
    assert np.all(np.abs(z - 1.5) < 0.02)
    assert res.truth["model"]["max_tilt_rad"] < 0.3


def test_hover_holds_position():
    res = simulate(path="hover", duration_s=10, rate_hz=RATE, seed=0, noise=False)
    f = res.flight
    for n in ("x", "y"):
        assert np.max(np.abs(f[n].values)) < 1e-6
    assert np.max(np.abs(f["z"].values - 1.5)) < 1e-6
    np.testing.assert_allclose(f["throttle"].values, 0.5, atol=1e-6)
    np.testing.assert_allclose(f["az"].values, G, atol=1e-6)


def test_control_flight_matches_tilt_drag_to_noise_level(control, control_clean):
    # noise-free: only the model's 2nd-order geometry and the differencing error remain
    rx, ry, _, _ = _residual(control_clean.flight)
    assert _rms(rx) < 0.03 and _rms(ry) < 0.03
    m = control.truth["model"]
    assert m["geometry_rmse_x"] < 0.02 and m["truth_rmse_x"] < 0.02
    # with mocap noise: the residual is the noise of the differentiated velocity
    rx, ry, _, _ = _residual(control.flight)
    hover = simulate(path="hover", duration_s=DUR, rate_hz=RATE, seed=3)
    hx, hy, _, _ = _residual(hover.flight)
    assert _rms(rx) < 1.15 * _rms(hx) and _rms(ry) < 1.15 * _rms(hy)
    assert _rms(rx) < 0.3
    assert abs(np.mean(rx)) < 0.03 and abs(np.mean(ry)) < 0.03


def test_wind_shifts_residual_by_kd_w():
    res = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, effects={"wind": (2.0, -1.0)})
    rx, ry, _, _ = _residual(res.flight)
    # drag acts on v - w: v_dot = ... - kD (v - w), so the residual is +kD w
    assert np.mean(rx) == pytest.approx(KD * 2.0, abs=0.05)
    assert np.mean(ry) == pytest.approx(KD * -1.0, abs=0.05)


def test_gust_residual_follows_the_wind():
    res = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, effects={"gust": None})
    rx, ry, _, idx = _residual(res.flight)
    wx = np.asarray(res.truth["true"]["wind_x"])[idx]
    wy = np.asarray(res.truth["true"]["wind_y"])[idx]
    s, c = _slope(KD * np.concatenate([wx, wy]), np.concatenate([rx, ry]))
    assert s == pytest.approx(1.0, abs=0.15) and c > 0.7
    assert np.std(wx) > 0.3   # it does gust


def test_quadratic_drag_residual():
    c = 0.1
    res = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, effects={"quadratic_drag": c})
    f = res.flight
    rx, ry, _, idx = _residual(f)
    vx, vy, vz = (v[idx] for v in _cols(f, "vx", "vy", "vz"))
    speed = np.sqrt(vx**2 + vy**2 + vz**2)
    s, corr = _slope(np.concatenate([-speed * vx, -speed * vy]), np.concatenate([rx, ry]))
    assert s == pytest.approx(c, rel=0.15) and corr > 0.6


def test_anisotropic_drag_residual():
    eff = parse_effects({"anisotropic_drag": None})["anisotropic_drag"]
    res = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, effects={"anisotropic_drag": None})
    f = res.flight
    rx, ry, _, idx = _residual(f)
    from droneid.core.frames import euler_to_matrix
    R = euler_to_matrix(*(v[idx] for v in _cols(f, "roll", "pitch", "yaw")))
    v = np.column_stack([c[idx] for c in _cols(f, "vx", "vy", "vz")])
    vb = np.einsum("nji,nj->ni", R, v)
    drag = np.einsum("nij,nj->ni", R, -vb * np.array([eff["kx"], eff["ky"], eff["kz"]]))
    pred = drag[:, :2] + KD * v[:, :2]          # true drag minus the model's -kD v
    s, corr = _slope(pred, np.column_stack([rx, ry]))
    assert s == pytest.approx(1.0, abs=0.15) and corr > 0.6


def test_attitude_bias_residual():
    b_roll, b_pitch = 0.03, -0.02
    res = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3,
                   effects={"attitude_bias": {"roll": b_roll, "pitch": b_pitch}})
    f = res.flight
    rx, ry, _, idx = _residual(f)
    yaw = f["yaw"].values[idx]
    # model(logged) - model(true) ~ g (cos(yaw) b_pitch + sin(yaw) b_roll) in x and
    # g (sin(yaw) b_pitch - cos(yaw) b_roll) in y; the residual has the opposite sign
    px = -G * (np.cos(yaw) * b_pitch + np.sin(yaw) * b_roll)
    py = -G * (np.sin(yaw) * b_pitch - np.cos(yaw) * b_roll)
    assert np.mean(rx - px) == pytest.approx(0.0, abs=0.04)
    assert np.mean(ry - py) == pytest.approx(0.0, abs=0.04)
    assert abs(np.mean(py)) > 0.2


def test_attitude_delay_residual_follows_attitude_rate():
    tau = 0.1
    res = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, effects={"attitude_delay": tau})
    f = res.flight
    rx, ry, t, idx = _residual(f)
    vx, vy, r, p, y = _cols(f, "vx", "vy", "roll", "pitch", "yaw")
    tx, ty = tilt_drag_model(0 * vx, 0 * vy, r, p, np.unwrap(y), KD, G)   # tilt terms only
    tt = f["vx"].t
    dtx = (tx[2:] - tx[:-2]) / (tt[2:] - tt[:-2])
    dty = (ty[2:] - ty[:-2]) / (tt[2:] - tt[:-2])
    s, corr = _slope(np.concatenate([dtx, dty]), np.concatenate([rx, ry]))
    assert s == pytest.approx(tau, rel=0.25) and corr > 0.6


def test_thrust_variation_residual():
    res = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, noise=False,
                   effects={"thrust_variation": None})
    f = res.flight
    rx, ry, t, idx = _residual(f)
    vx, vy, vz, r, p, y = _cols(f, "vx", "vy", "vz", "roll", "pitch", "yaw")
    assert np.ptp(f["z"].values) > 0.8
    az = np.gradient(vz, f["vz"].t)[idx]
    tx, ty = tilt_drag_model(0 * vx, 0 * vy, r, p, y, KD, G)
    k = (az + KD * vz[idx]) / G      # extra thrust over hover balance, relative
    s, corr = _slope(np.concatenate([k * tx[idx], k * ty[idx]]), np.concatenate([rx, ry]))
    assert s == pytest.approx(1.0, abs=0.2) and corr > 0.8


@pytest.mark.slow
def test_battery_sag_needs_more_throttle_not_a_new_tilt_law():
    eff = {"battery_sag": {"v_start": 12.6, "v_end": 10.8, "exponent": 2.0}}
    res = simulate(path="hover", duration_s=20, rate_hz=RATE, seed=3, effects=eff, noise=False)
    f = res.flight
    thr, volt = f["throttle"].values, f["battery_voltage"].values
    assert volt[0] > volt[-1] + 1.5
    # thrust per throttle falls as (V/V0)^2; after the integrator settles, throttle * gain = hover
    late = f["throttle"].t > 5
    hover = 0.5 * (volt[late] / 12.6) ** -2.0
    np.testing.assert_allclose(thr[late], hover, rtol=0.01)
    # the flight's tilt-drag law is unaffected (vertical balance still holds)
    res2 = simulate(path="eight", duration_s=DUR, rate_hz=RATE, seed=3, effects=eff, noise=False)
    rx, ry, _, _ = _residual(res2.flight)
    assert _rms(rx) < 0.04 and _rms(ry) < 0.04


def test_ground_effect_lowers_hover_throttle():
    radius, alt = 0.12, 0.15
    res = simulate(path="hover", duration_s=5, rate_hz=RATE, seed=0, noise=False,
                   effects={"ground_effect": {"rotor_radius_m": radius, "altitude_m": alt}})
    f = res.flight
    assert np.allclose(f["z"].values, alt, atol=1e-3)
    gain = 1.0 / (1.0 - (radius / (4 * alt)) ** 2)
    np.testing.assert_allclose(f["throttle"].values, 0.5 / gain, rtol=2e-3)


def test_effect_parsing_and_errors():
    assert parse_effects({"wind": (1, 2)})["wind"] == {"wx": 1.0, "wy": 2.0}
    assert parse_effects({"wind": None})["wind"] == EFFECTS["wind"]
    assert parse_effects(["quadratic_drag"]) == {"quadratic_drag": {"c": 0.1}}
    with pytest.raises(ConfigError, match="did you mean 'wind'"):
        simulate(effects={"wnd": 1})
    with pytest.raises(ConfigError, match="no parameter"):
        parse_effects({"wind": {"speed": 1}})
    with pytest.raises(ConfigError, match="at most 2"):
        parse_effects({"wind": (1, 2, 3)})
    with pytest.raises(ConfigError, match="must be >= 0"):
        parse_effects({"attitude_delay": -0.1})
    with pytest.raises(ConfigError, match="must be > 0"):
        parse_effects({"gust": {"tau_s": 0}})
    with pytest.raises(ConfigError, match="did you mean 'k_drag'"):
        simulate(k_dreg=0.3)
    with pytest.raises(ConfigError, match="path"):
        simulate(path="eigth")
    with pytest.raises(ConfigError):
        simulate(duration_s=-1)
    with pytest.raises(ConfigError):
        simulate(sim_rate_hz=100)


def test_internal_rate_at_least_200hz_and_rate_independence():
    """The same flight logged at 20 and 100 Hz agrees at common times (noise off)."""
    a = simulate(path="circle", duration_s=4, rate_hz=20, seed=0, noise=False)
    b = simulate(path="circle", duration_s=4, rate_hz=100, seed=0, noise=False)
    np.testing.assert_allclose(a.flight["x"].values, b.flight["x"].values[::5], atol=1e-9)
    assert math.isclose(a.truth["model"]["max_tilt_rad"], b.truth["model"]["max_tilt_rad"], rel_tol=1e-2)


def _rotor_cols(flight, prefix):
    return np.column_stack([flight[f"{prefix}{i}"].values for i in range(1, 5)])


def test_rotor_speeds_lag_their_commands_and_the_vehicle_follows_the_speeds():
    tau = 0.05
    eff = {"thrust_variation": {"amp_m": 0.3, "period_s": 2.5}}
    res = simulate(path="eight", duration_s=8, rate_hz=100, seed=3, noise=False, effects=eff, motor_tau_s=tau)
    rot = res.truth["rotors"]
    assert rot["motor_tau_s"] == tau
    w, u = _rotor_cols(res.flight, "rpm"), _rotor_cols(res.flight, "motor")
    t = res.flight["rpm1"].t
    gap = rot["rpm_max"] * u - w                       # command's settled speed minus the speed
    lhs = tau * np.gradient(w, t, axis=0)              # first-order lag: tau w' = gap
    assert np.max(np.abs(gap)) > 100.0                 # the lag is visible
    assert np.sqrt(np.mean((lhs - gap)[1:-1] ** 2)) < 0.02 * np.sqrt(np.mean(gap ** 2))
    # the acceleration follows the lagged speeds exactly, not the commands
    m = res.truth["model"]
    assert max(m["rotor_rmse_x"], m["rotor_rmse_y"], m["rotor_rmse_z"]) < 1e-9
    no_lag = simulate(path="eight", duration_s=8, rate_hz=100, seed=3, noise=False, effects=eff)
    np.testing.assert_allclose(_rotor_cols(no_lag.flight, "rpm"), rot["rpm_max"] * _rotor_cols(no_lag.flight, "motor"),
                               rtol=1e-12)


def test_rpm_logging_delay_shifts_only_the_logged_speeds():
    d = 0.04
    a = simulate(path="eight", duration_s=6, rate_hz=100, seed=3, noise=False)
    b = simulate(path="eight", duration_s=6, rate_hz=100, seed=3, noise=False, rpm_delay_s=d)
    assert b.truth["rotors"]["rpm_delay_s"] == d
    for n in ("x", "vx", "roll", "motor1", "throttle"):
        np.testing.assert_array_equal(a.flight[n].values, b.flight[n].values)
    k = int(round(d * 100))
    wa, wb = _rotor_cols(a.flight, "rpm"), _rotor_cols(b.flight, "rpm")
    np.testing.assert_allclose(wb[:-k], wa[k:], rtol=1e-9)     # logged at t = acting at t + d
    assert np.max(np.abs(wb[:-k] - wa[:-k])) > 5.0


def test_rotor_parameter_errors():
    with pytest.raises(ConfigError, match="'motor_tau_s' parameter of simulate must be >= 0"):
        simulate(duration_s=1, motor_tau_s=-0.01)
    with pytest.raises(ConfigError, match="'k_f' parameter of simulate must be > 0"):
        simulate(duration_s=1, k_f=0)


def test_battery_sag_slows_the_rotors_and_ground_effect_adds_thrust_at_the_same_speed():
    """Sag lowers the speed a command gives (the rpm law still holds exactly); ground effect
    raises the thrust a speed gives (the rpm law misses it by the gain)."""
    sag = simulate(path="hover", duration_s=20, rate_hz=RATE, seed=3, noise=False, effects={"battery_sag": None})
    m = sag.truth["model"]
    assert max(m["rotor_rmse_x"], m["rotor_rmse_y"], m["rotor_rmse_z"]) < 1e-9
    rot = sag.truth["rotors"]
    w, u = _rotor_cols(sag.flight, "rpm"), _rotor_cols(sag.flight, "motor")
    volt = sag.flight["battery_voltage"].values
    np.testing.assert_allclose(w, rot["rpm_max"] * u * (volt / 12.6)[:, None], rtol=1e-9)
    # same thrust, same speeds (the rotors differ only by the yaw-sweep torque)
    assert np.sqrt(np.mean(w[-1] ** 2)) == pytest.approx(rot["hover_rpm"], rel=1e-4)
    radius, alt = 0.12, 0.15
    ge = simulate(path="hover", duration_s=5, rate_hz=RATE, seed=0, noise=False,
                  effects={"ground_effect": {"rotor_radius_m": radius, "altitude_m": alt}})
    gain = 1.0 / (1.0 - (radius / (4 * alt)) ** 2)
    w_rms = np.sqrt(np.mean(_rotor_cols(ge.flight, "rpm") ** 2, axis=1))
    np.testing.assert_allclose(w_rms, ge.truth["rotors"]["hover_rpm"] / np.sqrt(gain), rtol=2e-3)
    assert ge.truth["model"]["rotor_rmse_z"] == pytest.approx(G * (1 - 1 / gain), rel=0.01)


def test_x_mix_signs_follow_the_ardupilot_quad_x_layout():
    """Motor 1 front-right CCW, 2 back-left CCW, 3 front-left CW, 4 back-right CW (FLU body)."""
    from droneid.simulation.simulator import DEFAULT_PARAMS, _Rotors
    rot = _Rotors(dict(DEFAULT_PARAMS))
    zero = np.zeros((1, 3))
    roll_left_up, nose_down, yaw_ccw = np.eye(3)[:, None, :]     # +x, +y, +z angular accelerations

    def sign(wdot):
        return np.sign(rot.torque_thrusts(zero, wdot)[0]).tolist()
    assert sign(roll_left_up) == [-1, 1, 1, -1]       # left rotors (2, 3) push harder
    assert sign(nose_down) == [-1, 1, -1, 1]          # rear rotors (2, 4) push harder
    assert sign(yaw_ccw) == [-1, -1, 1, 1]            # CW rotors (3, 4): their drag turns the body CCW
    dT = rot.torque_thrusts(np.array([[0.3, -0.2, 0.5]]), np.array([[2.0, -3.0, 1.0]]))
    assert abs(dT.sum()) < 1e-12                       # torques never change the collective
    # a command that would leave 0..1 keeps the collective and scales the torque part down
    u = rot.commands(np.array([4 * rot.t_max * 0.98]), np.array([[1.0, -1.0, 1.0, -1.0]]))
    assert np.all(u <= 1.0) and np.sum(u ** 2) * rot.t_max == pytest.approx(4 * rot.t_max * 0.98)


@pytest.mark.parametrize("expo,sag", [(0.35, False), (0.65, True)])
def test_command_driven_vehicle_follows_its_thrust_curve(expo, sag):
    """Issue 36: commands through the thrust curve (1 − e)u + e u², scaled by V/v_start under
    battery sag; without motor lag the curve on the logged commands is the vertical force exactly,
    with one the rotor speeds still are (the speeds carry the lag)."""
    from droneid.core.frames import euler_to_matrix
    from priors.thrust import thrust_curve
    eff = {"thrust_variation": {"amp_m": 0.5, "period_s": 3.0}}
    if sag:
        eff["battery_sag"] = {"v_start": 12.6, "v_end": 9.9, "exponent": 2.0}
    r = simulate(path="eight", duration_s=6.0, seed=3, noise=False, thrust_expo=expo, effects=eff)
    f, tr = r.flight, r.truth
    assert tr["rotors"]["thrust_expo"] == expo
    s = f["battery_voltage"].values / 12.6 if sag else 1.0
    u = np.column_stack([f[f"motor{i}"].values for i in range(1, 5)])
    R = euler_to_matrix(np.array(tr["true"]["roll"]), np.array(tr["true"]["pitch"]), np.array(tr["true"]["yaw"]))
    thrust = tr["rotors"]["k_cmd"] * np.sum(thrust_curve(u * np.atleast_1d(s)[:, None] if sag else u, expo), axis=1)
    az = thrust * R[:, 2, 2] - 9.81 - tr["params"]["k_drag"] * np.array(tr["true"]["vz"])
    assert np.max(np.abs(az - np.array(tr["az"]))) < 1e-4      # m/s²; a wrong curve is off by ~0.1
    lagged = simulate(path="eight", duration_s=6.0, seed=3, noise=False, thrust_expo=expo, effects=eff,
                      motor_tau_s=0.05)
    assert lagged.truth["model"]["rotor_rmse_z"] < 1e-6


def test_thrust_expo_out_of_range_is_refused():
    with pytest.raises(ConfigError, match="thrust_expo"):
        simulate(path="hover", duration_s=1.0, thrust_expo=1.2)
