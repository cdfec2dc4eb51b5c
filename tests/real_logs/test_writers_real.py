"""The project's Motive CSV writer against a real Motive 1.23 export (moved from
tests/unit/test_writers.py): the same header rows, keys and line endings."""
from __future__ import annotations

import pytest

from parsers.motive_writer import write_motive_csv

from conftest import real_log
from synth_flights import tilt_drag_flight

pytestmark = pytest.mark.real_logs


def test_motive_header_matches_real_export(tmp_path):
    flight = tilt_drag_flight(duration_s=2.0, rate_hz=20.0, quaternion=True)
    real = real_log("mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv")
    with open(real, newline="") as fh:
        real_lines = [fh.readline() for _ in range(7)]
    path = write_motive_csv(flight, tmp_path / "f.csv")
    with open(path, newline="") as fh:
        ours = [fh.readline() for _ in range(7)]
    assert all(ln.endswith("\r\n") for ln in ours) and all(ln.endswith("\r\n") for ln in real_lines)
    real_keys = real_lines[0].split(",")[0::2]
    assert ours[0].split(",")[0::2] == real_keys
    for a, b in zip(ours[1:], real_lines[1:]):
        assert a.split(",")[:2] == b.split(",")[:2]
    assert ours[5].rstrip() == real_lines[5].rstrip().split(",Rotation,Rotation,Rotation,Rotation,Position")[0] + \
        ",Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error"
    assert ours[6].rstrip() == ",".join(real_lines[6].rstrip().split(",")[:10])
