"""Multi-step prediction (droneid.simulation.rollout) against flights with known analytic solutions.

Planted truth: the log follows v̇x = −k_true vx (vx = v0 e^(−k_true t)) and v̇y = a_true; the models
integrate v̇x = −k vx and v̇y = a, so the error at horizon τ = h·dt is known in closed form for
every start: vx error v(t0)(e^(−kτ) − e^(−k_true τ)), vy error (a − a_true)τ, and the position
errors their integrals. RK4 at dt = 0.01 s is exact to ~1e-12 for these, so the tolerance is 1e-7.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from droneid.errors import ConfigError, DataError
from droneid.logs.flight import Flight, Signal
from droneid.fitting.closed_form import IdentifiedModel
from droneid.report.rollout import horizon_figures
from droneid.simulation.rollout import CONSTANT_VELOCITY, horizon_section, rollout_errors

DT, T_END = 0.01, 20.0
K_TRUE, V0, A_TRUE = 0.3, 2.0, 0.2
vx_, vy_, u_ = sp.symbols("vx vy throttle")


def _flight(drop=None, extra=()) -> Flight:
    t = np.round(np.arange(0.0, T_END + DT / 2, DT), 10)
    keep = np.ones(t.size, bool) if drop is None else ~((t > drop[0]) & (t < drop[1]))
    sig = {
        "vx": V0 * np.exp(-K_TRUE * t), "x": V0 / K_TRUE * (1 - np.exp(-K_TRUE * t)),
        "vy": A_TRUE * t, "y": 0.5 * A_TRUE * t ** 2,
        "vz": np.zeros_like(t), "z": np.ones_like(t),
        "roll": 0.01 * np.sin(t), "pitch": np.zeros_like(t), "yaw": np.zeros_like(t),
    }
    sigs = [Signal(n, t[keep] if n == "vx" else t, v[keep] if n == "vx" else v, "m/s") for n, v in sig.items()]
    sigs += list(extra)
    return Flight({s.name: s for s in sigs}, segments={"in_flight": ((0.0, T_END),)})


def _set(k, a):
    return {"vx_dot": IdentifiedModel("vx_dot", -sp.Float(k) * vx_), "vy_dot": IdentifiedModel("vy_dot", sp.Float(a))}


def test_linear_drag_and_constant_acceleration_reproduce_the_analytic_errors():
    k, a = 0.5, 0.35
    res = rollout_errors({"model": _set(k, a)}, _flight(), horizons=(1, 10, 50))
    assert res.dt_s == pytest.approx(DT)
    t = np.round(np.arange(0.0, T_END + DT / 2, DT), 10)
    for h in (1, 10, 50):
        tau = h * DT
        t0 = t[: t.size - h]            # starts whose horizon stays inside the flight
        v0 = V0 * np.exp(-K_TRUE * t0)
        ex_v = v0 * (np.exp(-k * tau) - np.exp(-K_TRUE * tau))
        ex_p = v0 * ((1 - np.exp(-k * tau)) / k - (1 - np.exp(-K_TRUE * tau)) / K_TRUE)
        ey_v = (a - A_TRUE) * tau
        ey_p = 0.5 * (a - A_TRUE) * tau ** 2
        e = res.rmse["model"][h]
        assert res.n_starts[h] == t0.size and res.skipped[h] == h
        assert e["vx"] == pytest.approx(math.sqrt(np.mean(ex_v ** 2)), rel=1e-7)
        assert e["vy"] == pytest.approx(abs(ey_v), rel=1e-7)
        assert e["position"] == pytest.approx(math.sqrt(np.mean(ex_p ** 2 + ey_p ** 2)), rel=1e-7)
        assert "vz" not in e
        # the constant-velocity baseline: v̂ = v(t0), p̂ = p(t0) + v(t0)τ
        cv = res.rmse[CONSTANT_VELOCITY][h]
        assert cv["vx"] == pytest.approx(math.sqrt(np.mean((v0 * (1 - np.exp(-K_TRUE * tau))) ** 2)), rel=1e-7)
        assert cv["vy"] == pytest.approx(A_TRUE * tau, rel=1e-7)
        cx = v0 * tau - v0 * (1 - np.exp(-K_TRUE * tau)) / K_TRUE
        cy = -0.5 * A_TRUE * tau ** 2
        assert cv["position"] == pytest.approx(math.sqrt(np.mean(cx ** 2 + cy ** 2)), rel=1e-7)
    assert res.position_axes["model"] == ("x", "y")


def test_the_true_model_has_no_error_and_the_baseline_does():
    res = rollout_errors({"true": _set(K_TRUE, A_TRUE)}, _flight(), horizons=(50,))
    assert res.rmse["true"][50]["vx"] < 1e-9 and res.rmse["true"][50]["position"] < 1e-9
    assert res.rmse[CONSTANT_VELOCITY][50]["vy"] == pytest.approx(A_TRUE * 0.5, rel=1e-9)


def test_a_gap_skips_the_starts_whose_horizon_crosses_it():
    # vx loses its samples in (10.0, 10.5) s: a gap of 51 periods (> 5) between 10.00 and 10.50 s
    res = rollout_errors({"true": _set(K_TRUE, A_TRUE)}, _flight(drop=(10.0, 10.5)), horizons=(1, 10, 50))
    n = 2001 - 49   # vx samples left
    for h in (1, 10, 50):
        # h starts before the end, h starts up to and including the last sample before the gap
        assert res.skipped[h] == 2 * h and res.n_starts[h] == n - 2 * h
        assert res.rmse["true"][h]["vx"] < 1e-9


def test_delays_are_applied_to_the_inputs():
    d, c = 0.1, 1.0
    t = np.round(np.arange(0.0, T_END + DT / 2, DT), 10)
    # the log: v̇x = c sin(t − d), i.e. vx = −c cos(t − d); the input u = sin(t) is logged undelayed
    base = _flight()
    f = base.with_signals(Signal("vx", t, -c * np.cos(t - d), "m/s"), Signal("throttle", t, np.sin(t), "1"))
    delayed = {"vx_dot": IdentifiedModel("vx_dot", c * u_, {"throttle": d})}
    undelayed = {"vx_dot": IdentifiedModel("vx_dot", c * u_)}
    res = rollout_errors({"delayed": delayed, "undelayed": undelayed}, f, horizons=(50,))
    # linear interpolation of sin at half steps (≤ dt²/8) integrated over 0.5 s: far below 1e-5
    assert res.rmse["delayed"][50]["vx"] < 1e-5
    assert res.rmse["undelayed"][50]["vx"] > 1e-2
    # starts whose delayed input would be read before the log begins are skipped
    assert res.skipped[50] == 50 + round(d / DT)
    assert res.position_axes["delayed"] == ()       # one horizontal axis: no position error


def test_unmodelled_axes_come_from_the_log():
    # vy_dot reads vx: with vx not modelled it is the logged vx, with vx modelled it is the state
    m = {"vy_dot": IdentifiedModel("vy_dot", sp.Float(A_TRUE) + sp.Float(1e-3) * vx_)}
    res = rollout_errors({"m": m}, _flight(), horizons=(10,))
    assert res.axes["m"] == ("vy",) and res.axes[CONSTANT_VELOCITY] == ("vy",)
    t0 = np.round(np.arange(0.0, T_END - 10 * DT + DT / 2, DT), 10)
    # error = 1e-3 ∫ vx dt over the horizon, vx from the log
    ex = 1e-3 * V0 / K_TRUE * (np.exp(-K_TRUE * t0) - np.exp(-K_TRUE * (t0 + 0.1)))
    assert res.rmse["m"][10]["vy"] == pytest.approx(math.sqrt(np.mean(ex ** 2)), rel=1e-6)


def test_vectorised_speed_7000_starts():
    import time
    long_t = 72.0
    t = np.round(np.arange(0.0, long_t, DT), 10)
    f = Flight({n: Signal(n, t, v, "m/s") for n, v in {
        "vx": np.sin(t), "vy": np.cos(t), "vz": 0 * t, "roll": 0.1 * np.sin(t), "pitch": 0.1 * np.cos(t),
        "yaw": 0 * t, "x": -np.cos(t), "y": np.sin(t), "z": 0 * t}.items()},
        segments={"in_flight": ((0.0, long_t),)})
    roll, pitch, yaw = sp.symbols("roll pitch yaw")
    m = {"vx_dot": IdentifiedModel("vx_dot", 9.81 * sp.tan(pitch) * sp.cos(yaw) / sp.cos(roll) - 0.3 * vx_),
         "vy_dot": IdentifiedModel("vy_dot", -9.81 * sp.tan(roll) * sp.cos(yaw) - 0.3 * vy_)}
    t_start = time.perf_counter()
    res = rollout_errors({"a": m, "b": m}, f, horizons=(1, 10, 50))
    wall = time.perf_counter() - t_start
    assert res.n_starts[1] > 7000
    assert wall < 10.0, f"{wall:.1f} s for {res.n_starts[1]} starts"


def test_bad_arguments_are_config_errors():
    f = _flight()
    with pytest.raises(ConfigError, match="horizons"):
        rollout_errors({"m": _set(1, 0)}, f, horizons=(0, 10))
    with pytest.raises(ConfigError, match="translational"):
        rollout_errors({"m": {"yaw_dot": IdentifiedModel("yaw_dot", sp.Float(0))}}, f)
    with pytest.raises(ConfigError, match="reserved"):
        rollout_errors({CONSTANT_VELOCITY: _set(1, 0)}, f)
    with pytest.raises(ConfigError, match="dt_s"):
        rollout_errors({"m": _set(1, 0)}, f, dt_s=-1)
    short = Flight({n: Signal(n, [0.0, 0.01, 0.02], [0.0, 0.0, 0.0], "m/s") for n in ("vx", "vy")},
                   segments={"in_flight": ((0.0, 0.02),)})
    with pytest.raises(DataError, match="no start point"):
        rollout_errors({"m": _set(1, 0)}, short, horizons=(50,))


def test_horizon_section_is_data_and_renders_pngs():
    sec = horizon_section(_set(0.5, 0.3), _set(0.28, 0.0), _set(K_TRUE, A_TRUE), _flight(), horizons=(1, 10, 50))
    assert set(sec["rmse"]) == {"identified", "empirical", "refit", CONSTANT_VELOCITY}
    assert sec["rmse"]["refit"]["50"]["vx"] < 1e-9 < sec["rmse"]["empirical"]["50"]["vx"]
    assert sec["seconds"] == pytest.approx([0.01, 0.1, 0.5])
    assert sec["segments"] and len(sec["segments"][0]["t"]) == 51
    pngs = horizon_figures(sec)
    assert set(pngs) == {"rollout_error_vs_horizon", "rollout_traces"}
    assert all(p[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs.values())
