"""Analytic synthetic data for the diagnosis tests: the tilt-drag model plus ONE planted effect.

Not a flight simulator: signals are smooth analytic functions of time and the target is the
planted law evaluated exactly (plus white noise), so the selection logic is tested on known truth.
Also :func:`decisions`: the part of a diagnosis result that two runs are compared on.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from droneid.dataset.data import Dataset
from droneid.core.expressions import parse_expression

G = 9.81
K_D = 0.28
PriorFeature = namedtuple("PriorFeature", "name expr description")
_SIGNALS = ("vx", "vy", "vz", "roll", "pitch", "yaw", "z", "battery_voltage", "throttle")


class TiltDragStub:
    """The paper's tilt-drag prior (3 features), standing in for priors.registry.get_prior."""

    _TEXT = {"vx_dot": ("g*cos(yaw)*tan(pitch)/cos(roll)", "g*sin(yaw)*tan(roll)", "-k_D*vx"),
             "vy_dot": ("g*sin(yaw)*tan(pitch)/cos(roll)", "-g*cos(yaw)*tan(roll)", "-k_D*vy")}

    def features(self, target, n_features=3):
        texts = self._TEXT[target]
        exprs = [parse_expression(t, _SIGNALS, {"g": G, "k_D": K_D}) for t in texts]
        if n_features == 1:
            return (PriorFeature("tilt_drag", sum(exprs), ""),)
        return tuple(PriorFeature(n, e, "") for n, e in zip(("tilt_pitch", "tilt_roll", "drag"), exprs))

    def inputs(self, target):
        return ("vx" if target == "vx_dot" else "vy", "pitch", "roll", "yaw")


def _attitude(t, phase):
    roll = 0.14 * np.sin(0.9 * t + phase) + 0.05 * np.sin(2.3 * t + 1 + phase)
    pitch = 0.14 * np.sin(0.7 * t + 0.5 + phase) + 0.05 * np.sin(1.9 * t + 2 * phase)
    yaw = (0.15 * t + phase + np.pi) % (2 * np.pi) - np.pi
    return roll, pitch, yaw


def _horizontal(duration_s, ts, phase):
    """Time grid and horizontal velocities (m/s) shared by both generators."""
    t = np.arange(0.0, duration_s, ts)
    vx = 2.5 * np.sin(0.3 * t + phase) + 0.8 * np.sin(1.1 * t)
    vy = 2.5 * np.cos(0.25 * t + 2 * phase) + 0.7 * np.sin(0.9 * t + 1)
    return t, vx, vy


def tilt(roll, pitch, yaw):
    gx = G * (np.cos(yaw) * np.tan(pitch) / np.cos(roll) + np.sin(yaw) * np.tan(roll))
    gy = G * (np.sin(yaw) * np.tan(pitch) / np.cos(roll) - np.cos(yaw) * np.tan(roll))
    return gx, gy


def make(effect=None, params=None, *, seed=0, duration_s=60.0, ts=0.05, noise=0.15, phase=0.0,
         drop=(), yaw=None):
    """{target: Dataset} for vx_dot and vy_dot with ``effect`` planted (None: control)."""
    p = dict(params or {})
    rng = np.random.default_rng(seed)
    t, vx, vy = _horizontal(duration_s, ts, phase)
    vz = 0.4 * np.sin(0.5 * t + phase)
    z = 2.0 + 0.8 * np.sin(0.5 * t + phase)
    roll, pitch, yaw_t = _attitude(t, phase)
    yaw = yaw_t if yaw is None else np.full(t.size, float(yaw))
    true_roll, true_pitch, true_yaw = roll, pitch, yaw
    if effect == "attitude_bias":      # logged = true + bias
        true_roll = roll - np.radians(p.get("roll_deg", 0.0))
        true_pitch = pitch - np.radians(p.get("pitch_deg", 0.0))
    if effect == "attitude_delay":     # logged(t) = true(t - tau)
        true_roll, true_pitch, true_yaw = _attitude(t + p["tau_s"], phase)
    gx, gy = tilt(true_roll, true_pitch, true_yaw)
    wx, wy = (p.get("wx", 0.0), p.get("wy", 0.0)) if effect == "wind" else (0.0, 0.0)
    ax = gx - K_D * (vx - wx)
    ay = gy - K_D * (vy - wy)
    if effect == "quadratic_drag":
        s = np.hypot(vx, vy)
        ax = ax - p["c"] * s * vx
        ay = ay - p["c"] * s * vy
    ax = ax + noise * rng.standard_normal(t.size)
    ay = ay + noise * rng.standard_normal(t.size)
    cols = {"vx": vx, "vy": vy, "vz": vz, "z": z, "roll": roll, "pitch": pitch, "yaw": yaw,
            "battery_voltage": 16.0 - 0.01 * t, "throttle": 0.5 + 0.02 * np.sin(t)}
    for d in drop:
        cols.pop(d, None)
    out = {}
    stub = TiltDragStub()
    for tgt, y in (("vx_dot", ax), ("vy_dot", ay)):
        ins = stub.inputs(tgt)
        out[tgt] = Dataset(np.column_stack([cols[n] for n in ins]), y, t, ins, tgt,
                           np.zeros(t.size, int), (f"synth{seed}",),
                           {k: v for k, v in cols.items() if k not in ins})
    return out


def flight_datasets(flight, ts=0.05, targets=("vx_dot", "vy_dot")):
    """{target: Dataset} from a simulated Flight whose signals share one time base: resample to
    ``ts`` by picking samples, central-difference the velocity. A stand-in for DatasetBuilder in
    tests that must not depend on it."""
    t_all = flight["vx"].t
    step = max(1, int(round(ts / np.median(np.diff(t_all)))))
    idx = np.arange(0, t_all.size, step)
    t = t_all[idx]
    cols = {n: flight[n].values[idx] for n in flight.signals}
    stub = TiltDragStub()
    out = {}
    for tgt in targets:
        v = cols["v" + tgt[1]]
        y = np.gradient(v, t)
        keep = slice(1, -1)
        ins = stub.inputs(tgt)
        out[tgt] = Dataset(np.column_stack([cols[n][keep] for n in ins]), y[keep], t[keep], ins, tgt,
                           np.zeros(t[keep].size, int), ("sim",),
                           {k: c[keep] for k, c in cols.items() if k not in ins})
    return out


K_T = 0.0257  # the rotor-thrust prior's nominal scale, m/s² per (10⁴ rpm)²


def make_rotor(effect=None, params=None, *, seed=0, duration_s=60.0, ts=0.05, noise=0.15, phase=0.0):
    """{target: Dataset} for vx_dot, vy_dot, vz_dot under the rotor-thrust law (thrust from
    four motor speeds along the exact body z axis, gravity, linear drag) with ``effect``
    planted: ``quadratic_drag`` (c horizontal, c_z vertical) or ``ground_effect`` (rotor radius
    R in m: Cheeseman-Bennett gain (R/4h)², h = max(z, 0.05) above the ground at z = 0; the
    flight then dips to the ground), None: control."""
    p = dict(params or {})
    rng = np.random.default_rng(seed)
    t, vx, vy = _horizontal(duration_s, ts, phase)
    vz = 1.5 * np.sin(0.5 * t + phase)
    z = 1.0 + 0.8 * np.sin(0.5 * t + phase) + 0.3 * np.sin(0.13 * t)
    roll, pitch, yaw = _attitude(t, phase)
    bx = np.cos(yaw) * np.sin(pitch) * np.cos(roll) + np.sin(yaw) * np.sin(roll)
    by = np.sin(yaw) * np.sin(pitch) * np.cos(roll) - np.cos(yaw) * np.sin(roll)
    bz = np.cos(roll) * np.cos(pitch)
    spec = (G + 1.5 * np.sin(0.7 * t + phase)) / bz            # specific thrust, m/s²
    w = 1e4 * np.sqrt(spec / (4 * K_T))
    rpm = [w * (1 + 0.01 * np.sin((1.3 + 0.2 * i) * t + i)) for i in range(4)]
    thrust = K_T * sum((r / 1e4) ** 2 for r in rpm)
    acc = {"x": thrust * bx - K_D * vx, "y": thrust * by - K_D * vy, "z": thrust * bz - G - K_D * vz}
    if effect == "quadratic_drag":
        s = np.hypot(vx, vy)
        acc["x"] = acc["x"] - p["c"] * s * vx
        acc["y"] = acc["y"] - p["c"] * s * vy
        acc["z"] = acc["z"] - p["c_z"] * np.abs(vz) * vz
    if effect == "ground_effect":
        z = z + 0.1
        gain = p["R"] ** 2 / (4 * np.maximum(z, 0.05)) ** 2
        for a, b in (("x", bx), ("y", by), ("z", bz)):
            acc[a] = acc[a] + gain * thrust * b
    cols = {"vx": vx, "vy": vy, "vz": vz, "z": z, "roll": roll, "pitch": pitch, "yaw": yaw,
            "battery_voltage": 16.0 - 0.01 * t, **{f"rpm{i + 1}": r for i, r in enumerate(rpm)}}
    out = {}
    for a in "xyz":
        tgt = f"v{a}_dot"
        ins = (f"v{a}", "roll", "pitch", "yaw", "rpm1", "rpm2", "rpm3", "rpm4")
        y = acc[a] + noise * rng.standard_normal(t.size)
        out[tgt] = Dataset(np.column_stack([cols[n] for n in ins]), y, t, ins, tgt,
                           np.zeros(t.size, int), (f"rotor{seed}",),
                           {k: v for k, v in cols.items() if k not in ins})
    return out


def decisions(r) -> dict:
    """Everything a diagnosis result's choices depend on or produce, without the test-flight
    report fields: equal for two runs that differ only in their test flights."""
    drop = {"test_rmse_before", "test_rmse_after", "test_rel_improvement"}
    cand = [{**c, "scores": [{k: v for k, v in s.items() if k not in drop} for s in c["scores"]]}
            for c in r.candidates]
    steps = [{"effect": s["effect"], "coefficients": s["coefficients"],
              "evidence": {k: v for k, v in s["evidence"].items() if k not in drop},
              "train": {t: (e["train"], e["cv"]) for t, e in s["rmse"].items()}} for s in r.steps]
    fin = [{"effect": f["effect"], "coefficients": f["coefficients"], "foldable": f["foldable"],
            "features": {t: [(x["name"], str(x["expr"]), x["coefficient"]) for x in fs]
                         for t, fs in f["features"].items()}} for f in r.final_effects]
    return {"added": r.effects_added, "conclusion": r.conclusion, "candidates": cand,
            "steps": steps, "final": fin, "untestable": r.untestable,
            "not_applicable": r.not_applicable, "not_detected": r.not_detected,
            "train": {t: (v["rmse_after"]["train"], v["rmse_after"]["cv"]) for t, v in r.targets.items()}}
