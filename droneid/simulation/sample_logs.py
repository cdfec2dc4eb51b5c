"""The sample logs droneid ships (``sample_logs/``), defined once so they regenerate identically.

:data:`SAMPLES` lists each simulated flight: the :func:`droneid.simulation.simulator.simulate` arguments and
the formats written. :func:`save` writes one simulation result (logs + ``<name>.truth.json``);
:func:`generate` writes every sample and ``sample_logs/README.md``. Outputs are byte-identical for
the same arguments (fixed epochs in every format, no wall-clock time anywhere).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from parsers.csv_writer import write_flat_csv
from parsers.mcap_writer import write_mcap
from parsers.motive_writer import write_motive_csv
from parsers.tlog_writer import write_tlog

from droneid.errors import ConfigError, did_you_mean
from droneid.core.frames import unwrap_angle
from droneid.core.io_util import atomic_write_json, atomic_write_text
from droneid.simulation.simulator import simulate, tilt_drag_model

__all__ = ["SampleSpec", "SAMPLES", "FORMATS", "save", "generate", "sample_command", "residual_rmse"]

#: output format -> file extension: MAVLink telemetry log, ROS 2 MCAP, OptiTrack Motive CSV (the
#: pose only, as a mocap system records it), flat CSV of every canonical signal (rotors included)
FORMATS = {"tlog": ".tlog", "mcap": ".mcap", "csv": ".csv", "flatcsv": ".flat.csv"}


@dataclass(frozen=True)
class SampleSpec:
    name: str
    description: str
    sim: dict = field(default_factory=dict)
    formats: tuple[str, ...] = ("tlog", "mcap", "csv", "flatcsv")


SAMPLES: tuple[SampleSpec, ...] = (
    SampleSpec(
        "paper_train_eight",
        "Training flight shaped like the paper's drone experiment: figure-eight (4 m x 2 m, 9 s per "
        "lap, two laps), 20 Hz, 361 samples, yaw sweeping +-0.8 rad, tilt up to ~0.22 rad. No "
        "undeclared effect: the tilt-drag model (k_D = 0.28) holds to the mocap noise level.",
        dict(path="eight", duration_s=18.0, rate_hz=20.0, seed=1)),
    SampleSpec(
        "paper_test_square",
        "Test flight of the pair: square path (2.4 m sides, 3.2 s per side, stopping at the "
        "corners), one lap, 20 Hz, 257 samples (the paper had 251). Speeds (up to 1.48 m/s) and "
        "tilts stay within the training eight's range, so the comparison tests the model, not "
        "its extrapolation. No undeclared effect.",
        dict(path="square", duration_s=12.8, rate_hz=20.0, seed=2, size_m=1.2)),
    SampleSpec(
        "wind_quadratic_eight",
        "Figure-eight like the training flight with two effects the tilt-drag model does not "
        "declare: a constant wind of (1.5, -1.0) m/s (drag acts on the air-relative velocity, so "
        "the residual gains +k_D w) and quadratic drag -0.15 |v_air| v_air.",
        dict(path="eight", duration_s=18.0, rate_hz=20.0, seed=3,
             effects={"wind": {"wx": 1.5, "wy": -1.0}, "quadratic_drag": {"c": 0.15}})),
    SampleSpec(
        "rotor_climb_eight",
        "Figure-eight with a vertical rhythm (altitude +-0.2 m every 1.2 s: thrust swings -40 % .. "
        "+60 % of hover) for the rotor-thrust prior. Its rotors lag their commands by 20 ms and "
        "its logged motor speeds lead the speeds that act by 40 ms (as a Crazyflie log does), so "
        "the rotor-thrust prior is exact with the speeds read 40 ms late (planted k_T and k_f in "
        "the truth JSON's `rotors`) and k_D = 0.28.",
        dict(path="eight", duration_s=18.0, rate_hz=20.0, seed=4,
             effects={"thrust_variation": {"amp_m": 0.2, "period_s": 1.2}},
             rpm_delay_s=0.04, motor_tau_s=0.02)),
)


def sample_command(spec: SampleSpec) -> str:
    """The ``droneid simulate`` command line that writes the same files as ``spec``."""
    s = spec.sim
    parts = ["droneid simulate", f"--path {s.get('path', 'eight')}",
             f"--duration {_num(s['duration_s'])}", f"--rate {_num(s.get('rate_hz', 100.0))}"]
    for eid, params in (s.get("effects") or {}).items():
        parts.append(f"--effect {eid}=" + ",".join(_num(v) for v in params.values()))
    for key, value in s.items():  # any other simulator parameter
        if key not in ("path", "duration_s", "rate_hz", "effects", "seed", "noise"):
            parts.append(f"--param {key}={_num(value)}")
    parts.append(f"--seed {s.get('seed', 0)}")
    parts.append(f"--format {','.join(spec.formats)} -o sample_logs --name {spec.name}")
    return " ".join(parts)


def _num(v) -> str:
    v = float(v)
    return str(int(v)) if v.is_integer() else repr(v)


def save(result, out_dir, name: str, formats=("tlog", "mcap", "csv")) -> list[Path]:
    """Write a :class:`~droneid.simulation.simulator.SimResult` as ``out_dir/name.<ext>`` for each format plus
    ``name.truth.json``; returns the written paths."""
    for f in formats:
        if f not in FORMATS:
            raise ConfigError(f"unknown output format '{f}'{did_you_mean(f, FORMATS)}; "
                              f"formats: {', '.join(FORMATS)}")
    if not name or any(c in name for c in "/\\") or name.startswith("."):
        raise ConfigError(f"The 'name' of the output must be a plain file stem. Got {name!r} instead.")
    writers = {f: _writer(f) for f in formats}
    out = Path(out_dir)
    written = []
    for f in formats:
        p = out / f"{name}{FORMATS[f]}"
        writers[f](result.flight, p)
        written.append(p)
    p = out / f"{name}.truth.json"
    atomic_write_json(p, result.truth, indent=1)
    written.append(p)
    return written


def _writer(fmt: str):
    """The writer function of an output format."""
    if fmt == "tlog":
        return write_tlog
    if fmt == "mcap":
        return write_mcap
    if fmt == "csv":
        return write_motive_csv
    return write_flat_csv


def residual_rmse(flight, k_drag: float = 0.28, g: float = 9.81) -> tuple[float, float, int]:
    """RMSE (m/s²) of the tilt-drag model against forward differences of vx, vy (the paper's
    targets), and the number of differences used. Signals are put on the vx time base."""
    t = flight["vx"].t
    cols = {}
    for n in ("vx", "vy", "roll", "pitch", "yaw"):
        s = flight[n]
        vals = unwrap_angle(s.values) if n == "yaw" else s.values
        cols[n] = vals if np.array_equal(s.t, t) else np.interp(t, s.t, vals)
    dt = np.diff(t)
    ax, ay = np.diff(cols["vx"]) / dt, np.diff(cols["vy"]) / dt
    mx, my = tilt_drag_model(cols["vx"], cols["vy"], cols["roll"], cols["pitch"], cols["yaw"], k_drag, g)
    rx, ry = ax - mx[:-1], ay - my[:-1]
    return (float(np.sqrt(np.mean(rx * rx))), float(np.sqrt(np.mean(ry * ry))), int(rx.size))


def generate(out_dir, names=None, progress=None) -> list[Path]:
    """Simulate and write the samples (all, or those in ``names``) and the README."""
    specs = SAMPLES if names is None else tuple(_spec(n) for n in names)
    written: list[Path] = []
    rows = []
    for i, spec in enumerate(specs):
        res = simulate(**spec.sim)
        written += save(res, out_dir, spec.name, spec.formats)
        rows.append((spec, res))
        if progress:
            progress(i + 1, len(specs), spec.name)
    if names is None:
        p = Path(out_dir) / "README.md"
        atomic_write_text(p, _readme(rows, out_dir))
        written.append(p)
    return written


def _spec(name: str) -> SampleSpec:
    for s in SAMPLES:
        if s.name == name:
            return s
    raise ConfigError(f"unknown sample log '{name}'{did_you_mean(name, [s.name for s in SAMPLES])}")


def _readme(rows, out_dir) -> str:
    rot, par = rows[0][1].truth["rotors"], rows[0][1].truth["params"]   # every sample: default rotors
    lines = [
        "# Sample logs",
        "",
        "Simulated quadrotor flights written by droneid's own writers (`droneid/simulation/simulator.py`,",
        "`parsers/*_writer.py`). Generated, do not edit: `make sample-logs` (or",
        "`droneid sample-logs --out sample_logs`) rewrites every file here byte for byte; the",
        "definitions are in `droneid/simulation/sample_logs.py`. Each flight is written as",
        "",
        "* `NAME.tlog`: MAVLink 2 telemetry log (ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED,",
        "  HIGHRES_IMU, SERVO_OUTPUT_RAW (motor commands), ESC_TELEMETRY_1_TO_4 (motor speeds),",
        "  VFR_HUD, SYS_STATUS, HEARTBEAT; NED/FRD),",
        "* `NAME.mcap`: ROS 2 MCAP (/drone/pose, /drone/twist, /drone/imu, /drone/battery,",
        "  /drone/throttle, /drone/thrust, /drone/motors, /drone/rpm1..4; ENU/FLU),",
        "* `NAME.csv`: OptiTrack Motive 1.23 CSV of the pose (Y-up: Motive X = east, Y = up, Z = south),",
        "* `NAME.flat.csv`: flat CSV of every signal under its canonical name (rpm1..4, motor1..4 too),",
        "* `NAME.truth.json`: the ground truth: simulator parameters, effects with their values, the",
        "  true world accelerations `t, ax, ay, az` at the logged times, the true noise-free states",
        "  and the rotor model (`rotors`: k_f, k_T, motor lag, rpm logging delay).",
        "",
        f"Rotors: X layout (ArduPilot order), thrust k_f rpm² each (k_f = {rot['k_f']:g} N/rpm²: the",
        f"{par['mass_kg']:g} kg vehicle hovers at {rot['hover_rpm']:.0f} rpm), commands u in 0..1 with thrust",
        "(t_max_n/4) u²; the vehicle accelerates with the rotors' thrust, so the rotor-thrust prior",
        f"holds with k_T = k_f 1e8 / m = {rot['k_T']:.3g} m/s² per (10⁴ rpm)². Logged speeds carry",
        f"{rot['rpm_noise']:g} rpm white noise.",
        "",
        "Time stamps in every file start at 2024-01-01 00:00:00 UTC (a fixed epoch, not the clock).",
        "Mocap-like noise: position 1 mm, attitude 0.2 deg, velocity from a 0.1 s least-squares",
        "slope of the 400 Hz positions. `RMSE` below: the paper's tilt-drag model against forward",
        "differences of the logged velocity (the paper's targets), m/s².",
        "",
        "| name | samples | effects | RMSE v̇x | RMSE v̇y | files |",
        "|---|---|---|---|---|---|",
    ]
    for spec, res in rows:
        rx, ry, _ = residual_rmse(res.flight)
        eff = res.truth["effects"]
        eff_s = "; ".join(f"{k} " + ", ".join(f"{p}={_num(v)}" for p, v in ps.items())
                          for k, ps in eff.items()) or "none"
        files = ", ".join(f"`{spec.name}{FORMATS[f]}`" for f in spec.formats) + f", `{spec.name}.truth.json`"
        lines.append(f"| {spec.name} | {len(res.flight['x'])} | {eff_s} | {rx:.3f} | {ry:.3f} | {files} |")
    lines.append("")
    for spec, res in rows:
        lines += [f"## {spec.name}", "", spec.description, "", "```", sample_command(spec), "```",
                  "", f"Signals: {', '.join(res.flight.names)}.", ""]
    return "\n".join(lines).rstrip("\n") + "\n"
