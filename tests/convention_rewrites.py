"""Rewrite a flat CSV log in a wrong convention (issue 41): the mistakes users make when they map
their own columns, each undone by one reader option (docs/logs.md, "Convention checks").

:func:`rewrite` reads a flat CSV with pandas, changes the columns droneid reads and writes the
result elsewhere; the test logs are never copied into the repository.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from droneid.core.frames import euler_to_quat, quat_to_euler

#: mistake -> (what it does, the reader option that undoes it)
MISTAKES = {
    "ned": ("x/y swapped, z and vz negated (NED read as ENU)", ["--world-frame", "ned"]),
    "frd": ("wy and wz negated (FRD body rates read as FLU)", ["--scale", "wy=-1", "--scale", "wz=-1"]),
    "ms": ("time stamps in milliseconds", ["--time-unit", "ms"]),
    "us": ("time stamps in microseconds", ["--time-unit", "us"]),
    "deg": ("body rates in deg/s", ["--scale", "wx=pi/180", "--scale", "wy=pi/180", "--scale", "wz=pi/180"]),
    "kmh": ("velocity in km/h", ["--scale", "vx=1/3.6", "--scale", "vy=1/3.6", "--scale", "vz=1/3.6"]),
    "swap": ("x and y (and vx, vy) swapped", ["--column", "x=y", "--column", "y=x", "--column", "vx=vy",
                                              "--column", "vy=vx"]),
    "yaw": ("yaw negated (clockwise), in the Euler columns and the quaternion", ["--scale", "yaw=-1"]),
}


def _col(df, name):
    for c in df.columns:
        if str(c).strip().lower() == name:
            return c
    raise KeyError(name)


def rewrite(src, dst, mistake: str) -> None:
    """Write ``src`` (a flat CSV with t, x y z, vx vy vz, wx wy wz, an attitude; or its
    DataFrame, left unchanged) to ``dst`` with ``mistake`` (a key of :data:`MISTAKES`) made."""
    df = src.copy() if isinstance(src, pd.DataFrame) else pd.read_csv(src, low_memory=False)
    c = {n: _col(df, n) for n in ("t", "x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz")}
    if mistake in ("ned", "swap"):
        for a, b in (("x", "y"), ("vx", "vy")):
            df[c[a]], df[c[b]] = df[c[b]].copy(), df[c[a]].copy()
        if mistake == "ned":
            df[c["z"]], df[c["vz"]] = -df[c["z"]], -df[c["vz"]]
    elif mistake == "frd":
        df[c["wy"]], df[c["wz"]] = -df[c["wy"]], -df[c["wz"]]
    elif mistake in ("ms", "us"):
        df[c["t"]] = df[c["t"]] * (1e3 if mistake == "ms" else 1e6)
    elif mistake == "deg":
        for n in ("wx", "wy", "wz"):
            df[c[n]] = np.degrees(df[c[n]])
    elif mistake == "kmh":
        for n in ("vx", "vy", "vz"):
            df[c[n]] = df[c[n]] * 3.6
    elif mistake == "yaw":
        names = [n for n in ("qw", "qx", "qy", "qz") if any(str(k).strip().lower() == n for k in df.columns)]
        if len(names) == 4:
            qc = [_col(df, n) for n in ("qw", "qx", "qy", "qz")]
            r, p, y = quat_to_euler(df[qc].to_numpy(float))
            q = euler_to_quat(r, p, -y)
            for i, col in enumerate(qc):
                df[col] = q[:, i]
        df[_col(df, "yaw")] = -df[_col(df, "yaw")]
    else:
        raise KeyError(f"unknown mistake {mistake!r}; known: {', '.join(MISTAKES)}")
    df.to_csv(dst, index=False)


def rewrite_all(src, folder, stem: str) -> dict:
    """Every mistake of :data:`MISTAKES` made to ``src``: {mistake: path of FOLDER/STEM_MISTAKE.csv}."""
    out, df = {}, pd.read_csv(src, low_memory=False)
    for m in MISTAKES:
        out[m] = folder / f"{stem}_{m}.csv"
        rewrite(df, out[m], m)
    return out


def reader_kwargs(words) -> dict:
    """read_flight keywords of reader-option words (``["--scale", "vx=1/3.6"]``), parsed by the
    CLI's own parser and :func:`droneid.commands._common.log_options`."""
    from droneid.cli import build_parser
    from droneid.commands._common import log_options
    args = build_parser(["inspect"]).parse_args(["inspect", "x.csv", *words])
    return {k: v for k, v in log_options(args).items() if v is not None}
