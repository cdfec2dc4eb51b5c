"""Write a :class:`Flight`'s pose as an OptiTrack Motive CSV export (format 1.23 layout).

Layout (CRLF line ends), as Motive 1.23 writes it for one rigid body::

    Format Version,1.23,Take Name,<name>,...,Rotation Type,Quaternion,Length Units,Meters,Coordinate Space,Global
    <blank>
    ,Type,Rigid Body x 8
    ,Name,<body> x 8
    ,ID,1 x 8
    ,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error
    Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,
    0,0.000000,<qX>,<qY>,<qZ>,<qW>,<X>,<Y>,<Z>,<mean marker error>

Axis mapping. Motive's world is Y-up and right-handed; droneid's is ENU. A rigid body defined
while the drone sits level facing east has its local axes aligned with Motive's world, so::

    Motive (X, Y, Z)        = (x_east, z_up, -y_north)          positions
    Motive quaternion       = M q M^-1, M = -90 deg about x:
    (qX, qY, qZ, qW)        = (qx, qz, -qy, qw)                 (droneid qw qx qy qz, FLU -> ENU)

and the reader inverts it: x = X, y = -Z, z = Y; (qw, qx, qy, qz) = (qW, qX, -qZ, qY).
Precision: 6 decimals (1 µm, 1e-6 quaternion units), like Motive's own export.
Only pose is written (Motive has no velocities, rates, IMU, motors).
"""
from __future__ import annotations

import os

import numpy as np

from droneid.errors import DataError
from droneid.core.io_util import atomic_write_text

from ._writer_util import complete_attitude, group, require_some

__all__ = ["write_motive_csv", "enu_to_motive", "motive_to_enu"]

_MEAN_MARKER_ERROR_M = 0.00015   # a plausible constant; the simulator has no markers


def enu_to_motive(x, y, z, qw, qx, qy, qz):
    """ENU position and FLU->ENU quaternion as Motive (X, Y, Z) and (qX, qY, qZ, qW)."""
    return (x, z, -np.asarray(y)), (qx, qz, -np.asarray(qy), qw)


def motive_to_enu(X, Y, Z, qX, qY, qZ, qW):
    """Inverse of :func:`enu_to_motive`: ((x, y, z), (qw, qx, qy, qz))."""
    return (X, -np.asarray(Z), Y), (qW, qX, -np.asarray(qZ), qY)


def write_motive_csv(flight, path, body: str = "drone") -> str:
    """Write ``flight`` (x y z and qw qx qy qz) to ``path`` as a Motive CSV (atomically)."""
    path = os.fspath(path)
    require_some(flight, path, "motive csv")
    flight = complete_attitude(flight)
    names = ("x", "y", "z", "qw", "qx", "qy", "qz")
    g = group(flight, names)
    if g is None:
        missing = [n for n in names if not flight.has(n)]
        raise DataError(f"cannot write {path} as a Motive CSV: the flight lacks {', '.join(missing)}")
    if "," in body or '"' in body:
        raise DataError(f"rigid body name {body!r} must not contain ',' or '\"'")
    t, v = g
    (X, Y, Z), (qX, qY, qZ, qW) = enu_to_motive(*(v[n] for n in names))
    q = np.column_stack([qX, qY, qZ, qW])
    q = np.where(q[:, 3:] < 0, -q, q)
    rate = float(1.0 / np.median(np.diff(t))) if t.size > 1 else 0.0
    n = t.size
    take = os.path.splitext(os.path.basename(path))[0]
    meta = ["Format Version", "1.23", "Take Name", take, "Take Notes", "",
            "Capture Frame Rate", f"{rate:.6f}", "Export Frame Rate", f"{rate:.6f}",
            "Capture Start Time", "2024-01-01 12.00.00.000 AM",
            "Total Frames in Take", str(n), "Total Exported Frames", str(n),
            "Rotation Type", "Quaternion", "Length Units", "Meters", "Coordinate Space", "Global"]
    lines = [",".join(meta), "",
             "," + ",".join(["Type"] + ["Rigid Body"] * 8),
             "," + ",".join(["Name"] + [body] * 8),
             "," + ",".join(["ID"] + ["1"] * 8),
             ",," + ",".join(["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"]),
             "Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,"]
    cols = np.column_stack([q, X, Y, Z])
    for i in range(n):
        vals = ",".join(f"{c:.6f}" for c in cols[i])
        lines.append(f"{i},{t[i]:.6f},{vals},{_MEAN_MARKER_ERROR_M:.6f}")
    atomic_write_text(path, "\r\n".join(lines) + "\r\n")
    return path
