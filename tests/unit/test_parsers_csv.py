"""Flat CSV and OptiTrack Motive CSV readers on planted data written in tmp_path."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.errors import ConfigError, LogFormatError
from droneid.core.frames import euler_to_quat
from parsers import detect_format, read_flight


def _write_flat(path, t, cols: dict):
    names = ["t"] + list(cols)
    rows = [",".join(names)]
    for i in range(len(t)):
        cells = [repr(float(t[i]))] + ["" if not np.isfinite(cols[n][i]) else repr(float(cols[n][i]))
                                       for n in cols]
        rows.append(",".join(cells))
    path.write_text("\n".join(rows) + "\n")


def test_flat_csv_planted_pose_and_derived_velocity(tmp_path):
    t = np.arange(0, 5, 0.01)
    x, y, z = np.sin(t), 2 * t, 1 + 0.1 * t ** 2
    p = tmp_path / "flat.csv"
    _write_flat(p, t + 100.0, {"x": x, "y": y, "z": z})
    assert detect_format(p) == "csv"
    f = read_flight(p)
    assert f.provenance.format == "csv"
    assert f["x"].start_s == 0.0                       # seconds from log start
    assert abs(f["x"].rate_hz - 100) < 1e-6
    mid = slice(5, -5)
    assert np.allclose(f["vx"].values[mid], np.cos(t)[mid], atol=1e-3)
    assert np.allclose(f["vy"].values[mid], 2.0, atol=1e-6)
    assert np.allclose(f["vz"].values[mid], 0.2 * t[mid], atol=1e-3)
    assert any("derived from position" in n for n in f.provenance.notes)


def test_flat_csv_euler_checked_against_quaternion(tmp_path):
    t = np.arange(0, 2, 0.01)
    roll, pitch, yaw = 0.3 * np.sin(t), 0.2 * np.cos(t), 2.5 * np.sin(0.5 * t)
    q = euler_to_quat(roll, pitch, yaw)
    p = tmp_path / "att.csv"
    _write_flat(p, t, {"qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3], "qw": q[:, 0],
                       "yaw": np.rad2deg(yaw), "pitch": -np.rad2deg(pitch), "roll": np.rad2deg(roll),
                       "x": t, "y": t, "z": t})
    f = read_flight(p)
    assert np.allclose(f["pitch"].values, pitch, atol=1e-9)   # from the quaternion
    assert np.allclose(f["roll"].values, roll, atol=1e-9)
    note = " ".join(f.provenance.notes)
    assert "in deg with pitch negated" in note


def test_flat_csv_euler_only_in_degrees(tmp_path):
    t = np.arange(0, 2, 0.01)
    p = tmp_path / "deg.csv"
    _write_flat(p, t, {"roll": np.full_like(t, 10.0), "pitch": np.full_like(t, -5.0),
                       "yaw": np.linspace(0, 350, t.size)})
    f = read_flight(p)
    assert np.allclose(f["roll"].values, np.deg2rad(10))
    assert f["yaw"].values.max() < np.pi


def test_flat_csv_nan_cells_and_bad_stamps_are_counted(tmp_path):
    t = np.arange(0, 1, 0.01)
    t[50] = t[49]            # duplicate
    t[70] = 0.2              # backwards
    x = np.arange(t.size, dtype=float)
    x[10] = np.nan           # blank cell
    p = tmp_path / "bad.csv"
    _write_flat(p, t, {"x": x, "vx": np.ones_like(t)})
    f = read_flight(p)
    sk = f.diagnostics.skipped
    assert sk["x: non-finite values"] == 1
    assert sk["x: duplicate time stamps"] == 1 and sk["x: backwards time stamps"] == 1
    assert len(f["x"]) == t.size - 3
    assert np.all(np.diff(f["x"].t) > 0)


def test_a_csv_cut_mid_row_drops_and_counts_its_last_row(tmp_path):
    """A copy stopped mid-row leaves a last row with fewer fields and no line end; pandas fills its
    missing cells with blanks and its last cell may itself be cut ("0.12" of "0.1234"), so the row
    is left out and counted, as a DataFlash record cut by the end of a file is. A file that merely
    lacks its final line end keeps every row."""
    t = np.arange(0, 1, 0.01)
    cols = {"x": np.arange(t.size) * 0.1234567, "y": np.ones_like(t), "vx": np.ones_like(t)}
    whole = tmp_path / "whole.csv"
    _write_flat(whole, t, cols)
    text = whole.read_text()
    cut = tmp_path / "cut.csv"
    cut.write_text(text[:text.rstrip("\n").rfind(",") - 3])       # inside the last row's x cell
    f = read_flight(cut)
    assert f.diagnostics.skipped["row cut by the end of the file (fewer fields than the header, no line end)"] == 1
    assert len(f["x"]) == t.size - 1 and np.allclose(f["x"].values, cols["x"][:-1])
    no_end = tmp_path / "no_end.csv"
    no_end.write_text(text.rstrip("\n"))
    g = read_flight(no_end)
    assert len(g["x"]) == t.size and not any("cut" in k for k in g.diagnostics.skipped)
    # a writer that leaves off empty trailing cells writes every row short: no row is cut
    short = tmp_path / "short_rows.csv"
    lines = text.rstrip("\n").split("\n")
    short.write_text("\n".join([lines[0] + ",note"] + lines[1:]))
    h = read_flight(short)
    assert len(h["x"]) == t.size and not any("cut" in k for k in h.diagnostics.skipped)


def test_flat_csv_without_needed_columns(tmp_path):
    p = tmp_path / "cols.csv"
    p.write_text("time,foo,bar\n0,1,2\n1,2,3\n")
    with pytest.raises(LogFormatError, match="no recognised signal columns.*foo"):
        read_flight(p)
    p.write_text("foo,x,y\n0,1,2\n1,2,3\n")
    with pytest.raises(LogFormatError, match="no time column"):
        read_flight(p)


def test_flat_csv_column_map(tmp_path):
    p = tmp_path / "map.csv"
    p.write_text("stamp,pos_e,foo\n0,1,2\n0.1,2,3\n0.2,3,4\n")
    f = read_flight(p, column_map={"t": "stamp", "x": "foo"})
    assert np.allclose(f["x"].values, [2, 3, 4])
    assert np.allclose(f["vx"].values, 10.0)
    with pytest.raises(ConfigError, match="did you mean 'foo'"):
        read_flight(p, column_map={"t": "stamp", "x": "fooo"})


def test_flat_csv_flags_become_segments(tmp_path):
    p = tmp_path / "flags.csv"
    rows = ["t,x,is_armed,is_flying"] + [f"{i * 0.1},{i},{i >= 2},{5 <= i < 8}" for i in range(10)]
    p.write_text("\n".join(rows) + "\n")
    f = read_flight(p)
    assert f.segments["armed"] == ((0.2, 0.9),)
    assert f.segments["in_flight"] == ((0.5, 0.8),)


# -------------------------------------------------------------------------------- Motive
def _motive(path, bodies: dict, t, rotation="Quaternion", units="Meters"):
    """A Motive 1.23-style export: ``bodies`` name -> (pos (n,3) Motive axes, rot (n,4 xyzw | n,3))."""
    meta = ["Format Version", "1.23", "Take Name", "synthetic", "Capture Frame Rate", "100.000000",
            "Rotation Type", rotation, "Length Units", units, "Coordinate Space", "Global"]
    types, names, ids, kinds, axes = [",Type"], [",Name"], [",ID"], [","], ["Frame,Time (Seconds)"]
    for name, (pos, rot) in bodies.items():
        rax = ["X", "Y", "Z", "W"] if rot.shape[1] == 4 else ["X", "Y", "Z"]
        for k, a in [("Rotation", a) for a in rax] + [("Position", a) for a in "XYZ"] + [("Mean Marker Error", "")]:
            types.append("Rigid Body"), names.append(name), ids.append("1"), kinds.append(k), axes.append(a)
    lines = [",".join(meta), "", ",".join(types), ",".join(names), ",".join(ids), ",".join(kinds), ",".join(axes)]
    for i in range(len(t)):
        cells = [str(i), f"{t[i]:.4f}"]
        for pos, rot in bodies.values():
            vals = list(rot[i]) + list(pos[i]) + [0.0001]
            cells += ["" if not np.isfinite(v) else f"{v:.6f}" for v in vals]
        lines.append(",".join(cells))
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode())


def test_motive_y_up_maps_to_enu_and_body_picks(tmp_path):
    t = 10 + np.arange(0, 3, 0.01)
    n = t.size
    # body "drone" climbs along Motive +Y (up) and moves along Motive +X; yawed +30 deg about +Y (up)
    pos = np.column_stack([0.5 * (t - 10), 1.0 + 0.2 * (t - 10), np.zeros(n)])
    a = np.deg2rad(30) / 2
    rot = np.tile([0.0, np.sin(a), 0.0, np.cos(a)], (n, 1))   # xyzw, about Motive +Y
    other = (np.zeros((n, 3)), np.tile([0, 0, 0, 1.0], (n, 1)))
    pos[40:43, 1] = np.nan                                       # occluded frames
    p = tmp_path / "take.csv"
    _motive(p, {"drone": (pos, rot), "wand": other}, t)
    assert detect_format(p) == "motive_csv"
    with pytest.raises(ConfigError, match="drone, wand"):
        read_flight(p)
    with pytest.raises(ConfigError, match="did you mean 'drone'"):
        read_flight(p, body="dron")
    f = read_flight(p, body="drone")
    assert f.diagnostics.skipped["occluded frames (blank cells)"] == 3
    assert f["x"].start_s == 0.0
    assert np.allclose(f["vz"].values[5:-5], 0.2, atol=1e-3)     # Motive +Y is up
    assert np.allclose(f["vx"].values[5:-5], 0.5, atol=1e-3)     # Motive +X is east
    assert np.allclose(f["y"].values, 0.0)
    # a rotation about the up axis is yaw, counter-clockwise seen from above in both frames
    assert np.allclose(f["yaw"].values, np.deg2rad(30), atol=1e-6)
    assert np.allclose(f["roll"].values, 0, atol=1e-6) and np.allclose(f["pitch"].values, 0, atol=1e-6)


def test_motive_pitch_sign(tmp_path):
    """Nose (Motive body +X) tilted DOWN toward -Y is positive pitch in droneid's convention."""
    t = np.arange(0, 1, 0.01)
    n = t.size
    a = np.deg2rad(-10) / 2   # rotation about Motive +Z by -10 deg takes +X toward -Y (down)
    rot = np.tile([0.0, 0.0, np.sin(a), np.cos(a)], (n, 1))
    p = tmp_path / "pitch.csv"
    _motive(p, {"quad": (np.zeros((n, 3)), rot)}, t)
    f = read_flight(p)
    assert np.allclose(f["pitch"].values, np.deg2rad(10), atol=1e-6)


def test_motive_units_and_custom_axes(tmp_path):
    from parsers import get_reader
    t = np.arange(0, 1, 0.01)
    n = t.size
    pos = np.column_stack([np.zeros(n), np.zeros(n), 1000 * t])   # Z-up export in mm
    p = tmp_path / "zup.csv"
    _motive(p, {"quad": (pos, np.tile([0, 0, 0, 1.0], (n, 1)))}, t, units="Millimeters")
    f = get_reader("motive_csv")(p, axes=("x", "y", "z"))
    assert np.allclose(f["vz"].values[2:-2], 1.0)
    with pytest.raises(ConfigError, match="determinant"):
        get_reader("motive_csv")(p, axes=("x", "y", "-z"))


def test_motive_euler_export_single_axis(tmp_path):
    """A rotation about Motive's up axis (+Y) only: yaw, whatever the Euler order convention."""
    t = np.arange(0, 1, 0.01)
    n = t.size
    rot = np.tile([0.0, 30.0, 0.0], (n, 1))              # X, Y, Z degrees
    p = tmp_path / "euler.csv"
    _motive(p, {"quad": (np.zeros((n, 3)), rot)}, t, rotation="XYZ")
    f = read_flight(p)
    assert np.allclose(f["yaw"].values, np.deg2rad(30), atol=1e-9)
    assert np.allclose(f["roll"].values, 0, atol=1e-9) and np.allclose(f["pitch"].values, 0, atol=1e-9)
    assert any("intrinsic" in note for note in f.provenance.notes)


def test_all_nan_csv_is_one_line_error(tmp_path):
    p = tmp_path / "nan.csv"
    p.write_text("t,x,y\n0,,\n0.1,,\n")
    with pytest.raises(LogFormatError) as ei:
        read_flight(p)
    assert "no usable csv signals" in str(ei.value) and "\n" not in str(ei.value)
