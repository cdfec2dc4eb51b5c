"""Motion-capture CSV files -> :class:`Flight`: OptiTrack Motive exports and flat CSVs.

**Motive** (``read_motive_csv``): row 1 holds ``key,value`` metadata (``Format Version``,
``Rotation Type``, ``Length Units``, ...); header rows are found by their first cells
(``,Type,``, ``,Name,``, ``,ID,``, ``,,`` = Rotation/Position/..., ``Frame,Time (Seconds),X,Y,Z,...``),
never by fixed offsets. Rigid-body columns only; several rigid bodies -> ``body=`` picks one by
name (ConfigError listing the names when it is missing or wrong). Frames with blank (occluded)
cells are skipped and counted.

Axes: Motive's default world is **Y-up**, right-handed. The default mapping ``axes=("x", "-z", "y")``
(a +90° rotation about X) gives ENU components ``(x_enu, y_enu, z_enu) = (X, -Z, Y)``. The rigid
body's own axes are assumed to have been aligned with the world axes when the body was created
(Motive's default), so the same mapping turns the body frame into FLU: forward = body +X,
left = body -Z, up = body +Y. Pass ``axes=`` (any signed permutation with determinant +1, e.g.
``("z", "x", "y")``) through ``parsers.get_reader("motive_csv")(path, axes=...)`` for other setups;
Z-up exports need ``axes=("x", "y", "z")``.
Rotation: ``Quaternion`` exports are used directly; Euler exports (``XYZ``, ``ZYX``, ... degrees)
are read as intrinsic rotations in that order (scipy ``from_euler`` with upper-case axes): this
is an assumption, not checked against a Motive Euler export; quaternion exports are preferred.

**Flat CSV** (``read_flat_csv``): one header row; columns are recognised by name (case-insensitive)::

    t / time / time_s / timestamp, x y z, qx qy qz qw, roll pitch yaw, vx vy vz, wx wy wz,
    ax ay az, vbat / battery_voltage, battery_current, lat lon alt, is_armed, is_flying,
    throttle (0..1) / throttle_pct (0..100), thrust (0..1: a throttle command; else N) / thrust_N,
    motor1.. / m1 / m1_thrust (0..1, PWM or % by range), rpm1 / rpm_1 / motor_rpm_1 / esc_rpm1 /
    m1_erpm (unit erpm: electrical rpm, said in the source) -- the full list: FLAT_ALIASES, docs/signals.md

plus ``column_map={"x": "pos_e", ...}`` (canonical name -> column) for anything else. Values are
taken as already in droneid's convention (ENU, FLU, SI). When both a quaternion and Euler
columns are present, roll/pitch/yaw are computed from the quaternion and the Euler columns are
only checked against it (units, order, signs: the finding goes into the provenance notes; the
Crazyflie files match Z-Y-X radians exactly). Euler columns alone are radians unless their
range says degrees. Missing velocity is derived from position (central differences, noted).
"""
from __future__ import annotations

import csv
import io
import logging
import os
import re

import numpy as np

from droneid.errors import ConfigError, LogFormatError, did_you_mean
from droneid.logs.flight import Flight, is_canonical
from droneid.core.frames import quat_to_euler, wrap_angle

from ._build import FlightBuilder, command_to_unit, intervals_from_bool
from ._registry import Reader

log = logging.getLogger(__name__)

__all__ = ["read_motive_csv", "read_flat_csv", "FLAT_ALIASES", "axes_matrix"]

_LENGTH = {"meters": 1.0, "meter": 1.0, "m": 1.0, "centimeters": 0.01, "millimeters": 0.001, "mm": 0.001}


def axes_matrix(axes) -> np.ndarray:
    """The proper rotation taking source components to ENU: row i selects ENU axis i."""
    A = np.zeros((3, 3))
    for i, a in enumerate(axes):
        a = a.strip().lower()
        sign = -1.0 if a.startswith("-") else 1.0
        j = "xyz".index(a.lstrip("+-"))
        A[i, j] = sign
    if not np.allclose(np.abs(A).sum(axis=0), 1) or not np.isclose(np.linalg.det(A), 1.0):
        raise ConfigError(f"The 'axes' parameter must be a signed permutation of x, y, z with "
                          f"determinant +1 (a rotation). Got {tuple(axes)!r} instead.")
    return A


# --------------------------------------------------------------------------------- Motive
def _read_text(path) -> str:
    with open(path, "rb") as f:
        raw = f.read()
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def read_motive_csv(path, body: str | None = None, axes=("x", "-z", "y")) -> Flight:
    """Read an OptiTrack Motive CSV export (see the module doc)."""
    path = os.fspath(path)
    A = axes_matrix(axes)
    text = _read_text(path)
    lines = text.splitlines()
    if not lines:
        raise LogFormatError(path, "the file is empty")
    first = next(csv.reader([lines[0]]))
    meta = {first[i].strip(): first[i + 1].strip() for i in range(0, len(first) - 1, 2)}
    header = {}
    data_start = None
    for i, line in enumerate(lines[1:60], start=1):
        cells = next(csv.reader([line])) if line else []
        if not cells:
            continue
        if cells[0] == "Frame":
            header["axis"] = cells
            data_start = i + 1
            break
        if cells[0] == "" and len(cells) > 1:
            key = cells[1] if cells[1] in ("Type", "Name", "ID") else "kind"
            header[key] = cells
    if data_start is None or "Name" not in header:
        raise LogFormatError(path, "Motive CSV without the 'Name' and 'Frame,Time' header rows")
    types = header.get("Type", [""] * len(header["Name"]))
    names, kinds, axis = header["Name"], header.get("kind", []), header["axis"]
    ncol = len(axis)

    def cell(row, j):
        return row[j] if j < len(row) else ""

    bodies = []
    for j in range(2, ncol):
        if cell(types, j) == "Rigid Body" and cell(names, j) and cell(names, j) not in bodies:
            bodies.append(cell(names, j))
    if not bodies:
        raise LogFormatError(path, "no rigid body columns in this Motive export")
    if body is None:
        if len(bodies) > 1:
            raise ConfigError(f"{path}: several rigid bodies ({', '.join(bodies)}); choose one "
                              f"with body= / --body NAME")
        body = bodies[0]
    elif body not in bodies:
        raise ConfigError(f"{path}: no rigid body named {body!r}; rigid bodies: {', '.join(bodies)}"
                          + did_you_mean(body, bodies))
    cols = {}
    for j in range(2, ncol):
        if cell(types, j) == "Rigid Body" and cell(names, j) == body:
            kind = cell(kinds, j)
            cols[(kind, cell(axis, j))] = j
    rot_type = meta.get("Rotation Type", "Quaternion")
    scale = _LENGTH.get(meta.get("Length Units", "Meters").lower())
    b = FlightBuilder(path, "motive_csv")
    if scale is None:
        b.warn(f"unknown Length Units {meta.get('Length Units')!r}: taken as metres")
        scale = 1.0
    b.vehicle = f"rigid body {body}"
    b.firmware = f"Motive CSV {meta.get('Format Version', '?')}"
    need = [("Position", a) for a in "XYZ"]
    rot_axes = ("X", "Y", "Z", "W") if rot_type == "Quaternion" else ("X", "Y", "Z")
    need += [("Rotation", a) for a in rot_axes]
    missing = [f"{k} {a}" for k, a in need if (k, a) not in cols]
    if missing:
        raise LogFormatError(path, f"rigid body {body!r} lacks columns: {', '.join(missing)}")
    use = [0, 1] + [cols[k] for k in need]
    import pandas as pd
    try:
        df = pd.read_csv(io.StringIO("\n".join(lines[data_start:])), header=None, usecols=use,
                         dtype=float, on_bad_lines="skip", engine="c")
    except (ValueError, pd.errors.ParserError) as exc:
        raise LogFormatError(path, f"unreadable Motive data rows ({exc})") from None
    arr = {j: df[j].to_numpy(float) for j in use}
    t = arr[1]
    block = np.stack([arr[cols[k]] for k in need], axis=-1)
    ok = np.isfinite(block).all(axis=1) & np.isfinite(t)
    b.skip("occluded frames (blank cells)", int((~ok).sum()))
    if not ok.any():
        raise LogFormatError(path, f"rigid body {body!r} has no complete frame (all occluded)")
    t = t[ok] - t[ok][0]
    pos = block[ok, :3] * scale @ A.T
    if rot_type == "Quaternion":
        qv = block[ok, 3:6] @ A.T
        q = np.column_stack([block[ok, 6], qv])
    else:
        from scipy.spatial.transform import Rotation
        order = rot_type.upper()
        if not re.fullmatch(r"[XYZ]{3}", order):
            raise LogFormatError(path, f"unknown Rotation Type {rot_type!r}")
        eul = block[ok, 3:6]
        by_axis = {a: eul[:, i] for i, a in enumerate("XYZ")}
        R = Rotation.from_euler(order, np.column_stack([by_axis[a] for a in order]), degrees=True)
        xyzw = R.as_quat()
        q = np.column_stack([xyzw[:, 3], xyzw[:, :3] @ A.T])
        b.notes.append(f"Motive Euler {order} read as intrinsic degrees (assumption)")
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(q[:, :1] < 0, -q, q)
    b.notes.append(f"Motive axes mapped to ENU as (x, y, z) = {tuple(axes)} of (X, Y, Z); "
                   f"body frame likewise (forward/left/up)")
    src = f"{body} Position"
    b.add_many(t, {"x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2]}, dict.fromkeys("xyz", "m"), src)
    _add_attitude(b, t, q, f"{body} Rotation ({rot_type})")
    return b.build()


def _add_attitude(b, t, q, src):
    b.add_many(t, {"qw": q[:, 0], "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3]},
               dict.fromkeys(("qw", "qx", "qy", "qz"), "1"), src)
    r, p, y = quat_to_euler(q)
    b.add_many(t, {"roll": r, "pitch": p, "yaw": y}, dict.fromkeys(("roll", "pitch", "yaw"), "rad"),
               src + " (to Euler)")


# ------------------------------------------------------------------------------- flat CSV
#: canonical name -> accepted column names (lower case), in order of preference
FLAT_ALIASES = {
    "t": ("t", "time", "time_s", "t_s", "time (seconds)", "timestamp", "time[s]", "sec"),
    "x": ("x", "pos_x", "px", "x_m"), "y": ("y", "pos_y", "py", "y_m"), "z": ("z", "pos_z", "pz", "z_m"),
    "vx": ("vx", "vel_x"), "vy": ("vy", "vel_y"), "vz": ("vz", "vel_z"),
    "qw": ("qw", "q_w", "quat_w"), "qx": ("qx", "q_x", "quat_x"), "qy": ("qy", "q_y", "quat_y"),
    "qz": ("qz", "q_z", "quat_z"),
    "roll": ("roll", "phi"), "pitch": ("pitch", "theta"), "yaw": ("yaw", "psi"),
    "wx": ("wx", "omega_x", "gyro_x"), "wy": ("wy", "omega_y", "gyro_y"), "wz": ("wz", "omega_z", "gyro_z"),
    "ax": ("ax", "acc_x"), "ay": ("ay", "acc_y"), "az": ("az", "acc_z"),
    "throttle": ("throttle", "throttle_cmd", "throttle_norm"),
    "throttle_pct": ("throttle_pct", "throttle_percent", "throttle_%", "throttle (%)"),
    # "thrust" without a unit is a normalised command when its values stay within 0..1
    # (the Crazyflie logs), else newtons; "thrust_cmd_n" is a command in N: a thrust
    "thrust": ("thrust_n", "thrust_cmd_n", "collective_thrust_n", "collective_thrust", "thrust",
               "thrust_cmd"),
    "battery_voltage": ("battery_voltage", "vbat", "voltage", "battery_v", "bat_v", "vbat_v",
                        "battery_voltage_v"),
    "battery_current": ("battery_current", "current", "battery_a", "battery_current_a"),
    "lat": ("lat", "latitude"), "lon": ("lon", "lng", "longitude"), "alt": ("alt", "altitude"),
    "armed": ("is_armed", "armed"), "flying": ("is_flying", "flying", "in_air"),
}
for _i in range(1, 17):
    FLAT_ALIASES[f"motor{_i}"] = (f"motor{_i}", f"m{_i}", f"m{_i}_thrust", f"motor_{_i}",
                                  f"motor{_i}_cmd", f"m{_i}_cmd", f"motor_cmd_{_i}")
    FLAT_ALIASES[f"rpm{_i}"] = (f"rpm{_i}", f"rpm_{_i}", f"motor_rpm_{_i}", f"motor{_i}_rpm",
                                f"m{_i}_rpm", f"esc_rpm{_i}", f"esc{_i}_rpm", f"esc_rpm_{_i}",
                                f"m{_i}_erpm", f"erpm{_i}", f"erpm_{_i}", f"esc{_i}_erpm")
_UNITS = {"x": "m", "y": "m", "z": "m", "vx": "m/s", "vy": "m/s", "vz": "m/s", "wx": "rad/s",
          "wy": "rad/s", "wz": "rad/s", "ax": "m/s^2", "ay": "m/s^2", "az": "m/s^2", "throttle": "1",
          "battery_voltage": "V", "battery_current": "A", "lat": "deg", "lon": "deg", "alt": "m"}
_TIME_SCALE = {"time_ms": 1e-3, "t_ms": 1e-3, "time_us": 1e-6, "timestamp_us": 1e-6, "t_us": 1e-6,
               "time_ns": 1e-9, "timestamp_ns": 1e-9}


def _match_columns(columns, column_map, path):
    lower = {c.strip().lower(): c for c in columns}
    found = {}
    for name, col in (column_map or {}).items():
        if col not in columns:
            raise ConfigError(f"column_map: column {col!r} (for {name!r}) is not in {path}"
                              + did_you_mean(col, columns))
        found[name] = col
    for name, aliases in FLAT_ALIASES.items():
        if name in found:
            continue
        for a in aliases + (tuple(k for k in _TIME_SCALE) if name == "t" else ()):
            if a in lower:
                found[name] = lower[a]
                break
    return found


def _to_bool(col) -> np.ndarray:
    s = np.asarray(col)
    if s.dtype.kind in "fiu":
        return np.nan_to_num(s.astype(float)) > 0.5
    return np.isin(np.char.lower(s.astype(str)), ("true", "1", "yes", "1.0"))


def read_flat_csv(path, column_map=None) -> Flight:
    """Read a flat CSV with one header row of recognisable column names (see the module doc)."""
    path = os.fspath(path)
    import pandas as pd
    def _read(**kw):
        try:
            return pd.read_csv(path, low_memory=False, **kw)
        except pd.errors.EmptyDataError:
            raise LogFormatError(path, "the file is empty") from None
        except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:
            raise LogFormatError(path, f"not a readable CSV ({str(exc).splitlines()[0]})") from None

    # the header first, then only the recognised columns (wide CSVs: read what is used)
    columns = [str(c) for c in _read(nrows=0).columns]
    found = _match_columns(columns, column_map, path)
    df = _read(usecols=sorted(set(found.values()))) if found else _read(nrows=0)
    shown = ", ".join(columns[:20]) + (", ..." if len(columns) > 20 else "")
    if "t" not in found:
        raise LogFormatError(path, f"no time column (t, time, timestamp, ...; or name it: --column t=COLUMN); "
                                   f"columns: {shown}")
    signals = [k for k in found if k not in ("t", "armed", "flying")]
    unknown = [k for k in (column_map or {}) if k not in FLAT_ALIASES or k in ("armed", "flying", "t")]
    bad = [k for k in unknown if k not in ("t", "armed", "flying") and not is_canonical(k)]
    if bad:
        raise ConfigError(f"--column: {bad[0]!r} is not a canonical signal name (x, vx, roll, "
                          f"throttle, thrust, motor1, rpm1, ...)" + did_you_mean(bad[0], FLAT_ALIASES))
    if not signals:
        raise LogFormatError(path, f"no recognised signal columns (x y z, qx qy qz qw, roll pitch yaw, "
                                   f"vx vy vz, ...; or name them: --column x=COLUMN ...); columns: {shown}")
    b = FlightBuilder(path, "csv")
    df = _misshapen_rows(b, df, path, len(columns))

    def num(name):
        return pd.to_numeric(df[found[name]], errors="coerce").to_numpy(float)

    t_raw = num("t")
    scale = _TIME_SCALE.get(found["t"].strip().lower(), 1.0)
    t_fin = t_raw[np.isfinite(t_raw)]
    if t_fin.size == 0:
        raise LogFormatError(path, f"the time column {found['t']!r} holds no numbers")
    t = (t_raw - t_fin[0]) * scale
    bad_rows = ~np.isfinite(t)
    b.skip("rows without a time stamp", int(bad_rows.sum()))
    for name in ("x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "ax", "ay", "az",
                 "battery_voltage", "battery_current", "lat", "lon", "alt"):
        if name in found:
            b.add(name, t, num(name), _UNITS[name], found[name])
    if "throttle" in found:       # normalised by the range its values show, as motor commands
        v, how = command_to_unit(num("throttle"))
        b.add("throttle", t, v, "1", f"{found['throttle']} ({how})")
    _rotor_columns(b, t, found, num)
    has_q = all(k in found for k in ("qw", "qx", "qy", "qz"))
    has_e = all(k in found for k in ("roll", "pitch", "yaw"))
    if has_q:
        q = np.column_stack([num(k) for k in ("qw", "qx", "qy", "qz")])
        norm = np.linalg.norm(q, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            q = q / norm
        q = np.where(q[:, :1] < 0, -q, q)
        _add_attitude(b, t, q, "qw/qx/qy/qz")
        if has_e:
            b.notes.append(_check_euler(q, np.column_stack([num(k) for k in ("roll", "pitch", "yaw")])))
    elif has_e:
        e = np.column_stack([num(k) for k in ("roll", "pitch", "yaw")])
        if np.nanmax(np.abs(e)) > 2 * np.pi * 1.05:
            e = np.deg2rad(e)
            b.notes.append("roll/pitch/yaw columns are in degrees (range > 2 pi): converted to rad")
        b.add_many(t, {"roll": e[:, 0], "pitch": e[:, 1], "yaw": wrap_angle(e[:, 2])},
                   dict.fromkeys(("roll", "pitch", "yaw"), "rad"), "roll/pitch/yaw columns")
        b.notes.append("roll/pitch/yaw columns taken as Z-Y-X Euler angles of FLU in ENU (no quaternion to check)")
    end = float(np.nanmax(t))
    for key, label in (("armed", "armed"), ("flying", "in_flight")):
        if key in found:
            ok = np.isfinite(t)
            b.segment(label, intervals_from_bool(t[ok], _to_bool(df[found[key]].to_numpy())[ok], end_s=end))
    b.in_flight_from_height()
    return b.build()


def _rotor_columns(b: FlightBuilder, t, found, num) -> None:
    """throttle / thrust / motorN / rpmN columns, normalised at this boundary (docs/signals.md)."""
    if "throttle_pct" in found and "throttle" not in found:
        b.add("throttle", t, num("throttle_pct") / 100.0, "1", f"{found['throttle_pct']} (% -> 0..1)")
    if "thrust" in found:
        col, v = found["thrust"], num("thrust")
        fin = v[np.isfinite(v)]
        unitless = col.strip().lower() in ("thrust", "thrust_cmd", "collective_thrust")
        if unitless and fin.size and fin.min() >= 0 and fin.max() <= 1 and "throttle" not in b.signals:
            b.add("throttle", t, v, "1", f"{col} (values within 0..1: a normalised command)")
        elif not (unitless and fin.size and fin.max() <= 1):
            b.add("thrust", t, v, "N", col + ("" if not unitless else " (values beyond 1: newtons)"))
    for i in range(1, 17):
        if f"motor{i}" in found:
            v, how = command_to_unit(num(f"motor{i}"))
            b.add(f"motor{i}", t, v, "1", f"{found[f'motor{i}']} ({how})")
        if f"rpm{i}" in found:
            col = found[f"rpm{i}"]
            if "erpm" in col.lower():
                b.add(f"rpm{i}", t, num(f"rpm{i}"), "erpm",
                      f"{col} (electrical rpm: rpm x motor pole pairs; the log states no pole-pair count)")
            else:
                b.add(f"rpm{i}", t, num(f"rpm{i}"), "rpm", col)


def _misshapen_rows(b: FlightBuilder, df, path, n_columns: int):
    """``df`` without a last row cut by the end of the file (its cells may be cut too), and both
    kinds of misshapen row counted on ``b``."""
    long_rows, cut_last = _row_shapes(path, n_columns)
    b.skip("rows with more fields than the header (extra fields ignored)", long_rows)
    if cut_last and len(df):
        b.skip("row cut by the end of the file (fewer fields than the header, no line end)", 1)
        return df.iloc[:-1]
    return df


def _row_shapes(path, n_columns: int) -> tuple[int, bool]:
    """(data rows with more comma-separated fields than the header, which pandas drops the extras
    of; whether the last row is cut: fewer fields than the header and than the row before it, no
    quotes and no line end, as a copy stopped mid-row leaves it, which pandas would fill with
    blanks)."""
    n, last, before = 0, b"", b""
    with open(path, "rb") as f:
        next(f, None)
        for line in f:
            if line.count(b",") >= n_columns and b'"' not in line:
                n += 1
            if line.strip():
                last, before = line, last
    fields = last.count(b",")
    # shorter than the header AND than the row before it (a writer that leaves off empty trailing
    # cells writes every row short), and no line end; a row with quotes is not judged
    cut = (bool(last) and not last.endswith(b"\n") and b'"' not in last and fields < n_columns - 1
           and bool(before) and fields < before.count(b","))
    return n, cut


def _check_euler(q, e) -> str:
    """Which convention the Euler columns follow, judged against the quaternion."""
    ok = np.isfinite(e).all(axis=1) & np.isfinite(q).all(axis=1)
    if not ok.any():
        return "roll/pitch/yaw columns empty: attitude from the quaternion"
    r, p, y = quat_to_euler(q[ok])
    ref = np.column_stack([r, p, y])
    e = e[ok]
    best = None
    for unit, factor in (("rad", 1.0), ("deg", np.pi / 180)):
        for sp in (1, -1):
            cand = e * factor * np.array([1, sp, 1])
            err = np.abs(wrap_angle(cand - ref)).max(axis=0)
            score = float(err.max())
            if best is None or score < best[0]:
                best = (score, unit, sp)
    score, unit, sp = best
    if score < 1e-3:
        return (f"roll/pitch/yaw columns equal the quaternion's Z-Y-X Euler angles in {unit}"
                + ("" if sp > 0 else " with pitch negated") + f" (max diff {score:.1e} rad); "
                "attitude taken from the quaternion")
    return (f"roll/pitch/yaw columns do NOT match the quaternion's Z-Y-X angles (best: {unit}, "
            f"max diff {score:.2f} rad); attitude taken from the quaternion")


def _first_cells(head: bytes) -> list[str] | None:
    """The cells of the first line of a text file's head (None for binary content)."""
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = head.decode("latin-1")
    if "\x00" in text:
        return None
    lines = text.splitlines()
    return [c.strip().strip('"') for c in lines[0].split(",")] if lines else []


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def sniff_motive(head: bytes) -> bool:
    """A Motive export's first row starts with ``Format Version``."""
    cells = _first_cells(head)
    return bool(cells) and cells[0] == "Format Version"


def sniff_flat(head: bytes) -> bool:
    """A flat CSV: a text first row with at least two non-numeric cells (the header)."""
    cells = _first_cells(head)
    return bool(cells) and len(cells) >= 2 and sum(1 for c in cells if c and not _is_number(c)) >= 2


READERS = (
    Reader("motive_csv", read_motive_csv, sniff_motive, order=30, extensions=(".csv",),
           options=("body",), description="OptiTrack Motive CSV export (rigid bodies; Y-up to ENU)"),
    Reader("csv", read_flat_csv, sniff_flat, order=90, extensions=(".csv",), options=("column_map",),
           description="flat CSV, one header row of recognisable column names"),
)
