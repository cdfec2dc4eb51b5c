"""Damaged logs never traceback, hang or flood (issue 14).

Small logs of every format the project writes (tlog, MCAP, Motive CSV, flat CSV, DataFlash and
PX4 sdlog2 via the test writer, a minimal ULog) are mutated with a fixed seed: byte flips, truncation, inserted
garbage, zeroed regions, header damage. ``droneid inspect`` runs in-process on each, in a daemon
thread with a per-file time limit; it must exit 0, or exit 2 with exactly ONE stderr line, and
never print a traceback or more than one warning line. Regression tests pin each case of the
issue. A ``slow`` variant mutates the real logs: tests/real_logs/test_fuzz_real.py.
"""
from __future__ import annotations

import random
import struct
import time
from pathlib import Path

import numpy as np
import pytest

from droneid.errors import LogFormatError
from droneid.logs.flight import Flight, Signal
from parsers import read_flight

from dataflash_fixture import DataFlashWriter, sdlog2_log
from fuzz_check import check_inspect, inspect_in_process, mutate


# ------------------------------------------------------------------------------ small logs
def _flight(n=60, dt=0.05) -> Flight:
    t = np.arange(n) * dt
    sig = {
        "x": np.sin(t), "y": np.cos(t), "z": 1 + 0.1 * t, "roll": 0.1 * np.sin(t),
        "pitch": 0.1 * np.cos(t), "yaw": 0.2 * t, "wx": 0.1 + 0 * t, "wy": 0 * t, "wz": 0.2 + 0 * t,
        "ax": 0 * t, "ay": 0 * t, "az": 9.8 + 0 * t, "throttle": 0.5 + 0 * t,
        "battery_voltage": 12 - 0.01 * t, "motor1": 0.4 + 0 * t, "motor2": 0.5 + 0 * t,
    }
    units = {"x": "m", "y": "m", "z": "m", "roll": "rad", "pitch": "rad", "yaw": "rad",
             "wx": "rad/s", "wy": "rad/s", "wz": "rad/s", "ax": "m/s^2", "ay": "m/s^2",
             "az": "m/s^2", "throttle": "1", "battery_voltage": "V", "motor1": "1", "motor2": "1"}
    return Flight({k: Signal(k, t, v, units[k], "test") for k, v in sig.items()},
                  segments={"armed": ((0.0, t[-1]),)})


def _dataflash_bytes(n=80) -> bytes:
    w = DataFlashWriter()
    w.fmt("ATT", "QfffI", "TimeUS,Roll,Pitch,Yaw,DesYaw")
    w.fmt("GPS", "QBiif", "TimeUS,Status,Lat,Lng,Alt")
    w.fmt("IMU", "QffffffB", "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,I")
    w.fmt("PARM", "QNf", "TimeUS,Name,Value")
    w.add("PARM", 0, "MOT_PWM_MIN", 1000.0)
    for i in range(n):
        tu = 1_000_000 + i * 20_000
        w.add("ATT", tu, 1.0, 2.0, 90.0, 0)
        w.add("IMU", tu, 0.1, 0.2, 0.3, 0.0, 0.0, -9.8, 0)
        if i % 5 == 0:
            w.add("GPS", tu, 3, 470000000, 80000000, 400.0)
    return w.bytes()


def _ulog_bytes() -> bytes:
    """A minimal valid ULog: header, one format, one subscription, a few samples."""
    def msg(typ, body):
        return struct.pack("<HB", len(body), ord(typ)) + body
    out = bytearray(b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 1_000_000))
    out += msg("F", b"vehicle_local_position:uint64_t timestamp;float x;float y;float z;"
                    b"float vx;float vy;float vz;")
    out += msg("A", struct.pack("<BH", 0, 1) + b"vehicle_local_position")
    for i in range(50):
        out += msg("D", struct.pack("<HQ6f", 1, 1_000_000 + i * 20_000, i, 0, -1, 1, 0, 0))
    return bytes(out)


@pytest.fixture(scope="module")
def small_logs(tmp_path_factory) -> dict[str, bytes]:
    from parsers.mcap_writer import write_mcap
    from parsers.motive_writer import write_motive_csv
    from parsers.tlog_writer import write_tlog
    d = tmp_path_factory.mktemp("small")
    f = _flight()
    out = {}
    for ext, write in ((".tlog", write_tlog), (".mcap", write_mcap), (".motive.csv", write_motive_csv)):
        p = d / f"log{ext}"
        write(f, p)
        out[ext] = p.read_bytes()
    t = np.arange(50) * 0.01
    out[".csv"] = ("t,x,y,z,vx,vy,vz,roll,pitch,yaw,m1_erpm,thrust\n" + "".join(
        f"{ti:.3f},{ti},{2 * ti},1,1,2,0,0.1,0.2,0.3,{20000 + i},0.5\n" for i, ti in enumerate(t))).encode()
    out[".bin"] = _dataflash_bytes()
    out[".px4log"] = sdlog2_log(n=60).bytes()
    out[".ulg"] = _ulog_bytes()
    return out


@pytest.mark.slow
def test_fuzz_small_logs_of_every_format(small_logs, tmp_path):
    rng = random.Random(20261123)
    seen = {0: 0, 2: 0}
    t0 = time.perf_counter()
    for ext, data in sorted(small_logs.items()):
        assert check_inspect(_write(tmp_path / f"intact{ext}", data), f"intact {ext}") == 0
        for k in range(30):
            kind, bad = mutate(data, rng)
            p = _write(tmp_path / f"m{k}{ext}", bad)
            seen[check_inspect(p, f"{ext} #{k} ({kind})")] += 1
    assert seen[0] and seen[2], seen       # the mutations exercise both outcomes
    assert time.perf_counter() - t0 < 60


def _write(p: Path, data: bytes) -> Path:
    p.write_bytes(data)
    return p


# ------------------------------------------------------------------------------ regressions
def test_ulog_reader_loop_is_stopped(tmp_path):
    """pyulog seeks back forever on a message claiming more bytes than remain, behind zeros."""
    p = _write(tmp_path / "loop.ulg", b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 0) + bytes(1100)
               + b"\x00\x04\x00" + b"\x01" * 10)
    rc, lines, dt = inspect_in_process(p)
    assert rc == 2 and len(lines) == 1 and "pyulog stopped making progress" in lines[0], lines
    assert dt < 10


def test_ulog_topic_without_timestamp_is_skipped(tmp_path):
    """A damaged format definition without 'timestamp' (was: KeyError 'timestamp')."""
    good = _ulog_bytes()
    bad = good.replace(b"uint64_t timestamp;", b"uint64_t timestxmp;")
    with pytest.raises(LogFormatError, match="no usable ulog signals"):
        read_flight(_write(tmp_path / "nots.ulg", bad))
    f = read_flight(_write(tmp_path / "ok.ulg", good))
    assert f.has("x", "vx") and len(f["x"]) == 50


@pytest.mark.parametrize("field", ["Status", "Lat", "AccX", "Value"])
def test_dataflash_fmt_missing_fields_is_skipped_and_counted(tmp_path, field):
    """A corrupt FMT renaming a column (was: KeyError 'Status' / 'Lat' / 'AccX', unpack error)."""
    data = _dataflash_bytes()
    cols = {"Status": b"TimeUS,Status,Lat", "Lat": b"TimeUS,Status,Lat",
            "AccX": b"GyrZ,AccX", "Value": b"Name,Value"}[field]
    bad = data.replace(cols, cols.replace(field.encode(), b"Q" * len(field)), 1)
    assert bad != data
    f = read_flight(_write(tmp_path / "fmt.bin", bad))
    assert any("damaged FMT" in k for k in f.diagnostics.skipped), dict(f.diagnostics.skipped)
    assert f.has("roll")


def test_dataflash_damage_is_counted_and_quiet(tmp_path, capfd):
    """Garbage between records: pymavlink prints a line per byte; the count is exact (planted)
    and the terminal quiet."""
    data = _dataflash_bytes()
    at = data.find(b"\xa3\x95", len(data) // 2)      # a record boundary
    n_garbage = 700
    bad = data[:at] + b"\x11" * n_garbage + data[at:]
    f = read_flight(_write(tmp_path / "garbage.bin", bad))
    out, err = capfd.readouterr()
    assert out == "" and err == "", (out[:200], err[:200])
    assert f.diagnostics.skipped["corrupt bytes outside any record (pymavlink resynchronised)"] == n_garbage
    assert any("reader library output suppressed" in w for w in f.diagnostics.warnings)
    assert len(f["roll"]) == 80            # no record lost


def test_px4log_damage(tmp_path):
    """A PX4 sdlog2 log cut mid-record or with garbage inside reads up to / around the damage,
    counted; one cut before its first TIME record is refused in one line naming the file."""
    data = sdlog2_log().bytes()
    cut = _write(tmp_path / "cut.px4log", data[: len(data) // 2 + 5])
    f = read_flight(cut)
    assert f.provenance.format == "px4log" and f.diagnostics.skipped["record cut by the end of the file"] == 1
    assert check_inspect(cut, "cut px4log") == 0
    at = data.find(b"\xa3\x95", len(data) // 2)
    garbage = _write(tmp_path / "garbage.px4log", data[:at] + b"\x11" * 300 + data[at:])
    f = read_flight(garbage)
    assert f.diagnostics.skipped["corrupt bytes outside any record (pymavlink resynchronised)"] == 300
    assert len(f["roll"]) == 100
    head = _write(tmp_path / "head.px4log", data[: data.find(b"MAV_TYPE") + 20])   # FMTs and PARM only
    rc, lines, _ = inspect_in_process(head)
    assert rc == 2 and len(lines) == 1, lines
    assert "head.px4log" in lines[0] and "no TIME records" in lines[0] and "Traceback" not in lines[0]


def test_reader_exception_becomes_one_line(tmp_path, monkeypatch):
    """Any non-droneid exception escaping a reader becomes a LogFormatError naming the file."""
    import parsers.mavlink_log as ml
    monkeypatch.setattr(ml, "_convert", lambda *a: {}["boom"])
    p = _write(tmp_path / "x.tlog", _tlog_of(_flight()))
    with pytest.raises(LogFormatError, match=r"x\.tlog: unreadable tlog log.*KeyError"):
        read_flight(p)


def _tlog_of(flight) -> bytes:
    import tempfile
    from parsers.tlog_writer import write_tlog
    with tempfile.TemporaryDirectory() as d:
        return Path(write_tlog(flight, Path(d) / "f.tlog")).read_bytes()


def test_csv_extra_fields_and_absurd_time_are_counted(tmp_path):
    p = _write(tmp_path / "x.csv", b"t,x,y\n0,1,2\n0.1,1,2,3,4\n0.2,1,2\n1e300,1,2\n0.3,1,2\n")
    f = read_flight(p)
    sk = f.diagnostics.skipped
    assert sk["rows with more fields than the header (extra fields ignored)"] == 1
    assert sk["x: time stamps beyond 1e+08 s from the log start"] == 1
    np.testing.assert_allclose(f["x"].t, [0, 0.1, 0.2, 0.3])
