"""Format detection, the reader registry, and bad input for every format (files made in tmp_path)."""
from __future__ import annotations

import os

import numpy as np
import pytest

from droneid.errors import ConfigError, LogFormatError
from parsers import FORMATS, READERS, detect_format, get_reader, read_flight

from conftest import REAL_LOGS, real_log


def test_every_registered_reader_is_reachable_by_name():
    assert set(FORMATS) == {"dataflash", "tlog", "ulog", "mcap", "motive_csv", "csv"}
    for name in READERS:
        assert callable(get_reader(name))


def test_unknown_format_name_suggests_the_nearest():
    with pytest.raises(ConfigError, match="did you mean 'ulog'"):
        get_reader("ulgo")
    with pytest.raises(ConfigError, match="unknown log format"):
        read_flight(__file__, format="nope")


@pytest.mark.parametrize("head, fmt", [
    (b"ULog\x01\x12\x35\x01" + bytes(40), "ulog"),
    (b"\x89MCAP0\r\n" + bytes(40), "mcap"),
    (b"\xa3\x95\x80\x80YFMT" + bytes(40), "dataflash"),
    (b"Format Version,1.23,Take Name,x\r\n\r\n,Type,Rigid Body\r\n", "motive_csv"),
    (b"t,x,y,z\n0,1,2,3\n", "csv"),
])
def test_detect_by_content_not_extension(tmp_path, head, fmt):
    p = tmp_path / "log.weird"           # no telling extension
    p.write_bytes(head)
    assert detect_format(p) == fmt


def test_detect_tlog_by_timestamp_and_magic(tmp_path):
    from tlog_fixture import tlog_bytes
    p = tmp_path / "x.bin"               # misleading extension: content wins
    p.write_bytes(tlog_bytes([("heartbeat", 0.0, {})]))
    assert detect_format(p) == "tlog"


def test_empty_file_is_one_line_error(tmp_path):
    p = tmp_path / "empty.bin"
    p.write_bytes(b"")
    with pytest.raises(LogFormatError) as ei:
        read_flight(p)
    assert str(p) in str(ei.value) and "empty" in str(ei.value) and "\n" not in str(ei.value)


def test_random_bytes_are_rejected(tmp_path):
    p = tmp_path / "noise.tlog"
    p.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(LogFormatError, match="unrecognised log format"):
        read_flight(p)


def test_missing_file_is_oserror(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_flight(tmp_path / "nope.bin")


def test_option_for_another_format_is_rejected(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("t,x\n0,1\n0.1,2\n")
    with pytest.raises(ConfigError, match="topics"):
        read_flight(p, topics={"pose": "/x"})


@pytest.mark.parametrize("rel", ["ardupilot/copter33_quad_log171.bin", "mavlink/copter357_quad_mission1.tlog",
                                 "px4/x500_sitl_events.ulg", "mcap/sportcub_fixedwing_qualisys.mcap"])
def test_garbage_with_a_real_magic_is_a_log_format_error(tmp_path, rel):
    """The real file's first bytes followed by noise: an error naming the file, or a flight with
    its damage counted; never a crash with a foreign exception."""
    src = real_log(rel)
    head = src.read_bytes()[:64]
    p = tmp_path / ("bad" + src.suffix)
    p.write_bytes(head + np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    try:
        f = read_flight(p)
    except LogFormatError as exc:
        assert str(p) in str(exc)
    else:
        assert f.diagnostics.total_skipped > 0 or f.diagnostics.warnings


@pytest.mark.parametrize("rel, frac", [("ardupilot/copter33_quad_log171.bin", 0.5),
                                       ("mavlink/copter357_quad_mission1.tlog", 0.5),
                                       ("mcap/sportcub_fixedwing_qualisys.mcap", 0.5),
                                       ("px4/x500_sitl_events.ulg", 0.5)])
def test_truncated_real_log_reads_up_to_the_cut(tmp_path, rel, frac):
    src = real_log(rel)
    data = src.read_bytes()
    cut = int(len(data) * frac) + 3          # +3: land inside a record
    p = tmp_path / ("cut" + src.suffix)
    p.write_bytes(data[:cut])
    full = read_flight(src)
    f = read_flight(p)
    assert f.has("roll") or f.has("x")
    name = "roll" if f.has("roll") else "x"
    assert 0.2 * full.duration_s < f.duration_s < 0.9 * full.duration_s
    assert len(f[name]) < len(full[name])
    if src.suffix in (".bin", ".tlog", ".mcap"):
        assert f.diagnostics.total_skipped >= 1 or f.diagnostics.warnings


def test_real_80k_dataflash_prefix_is_flagged_as_cut():
    f = read_flight(real_log("ardupilot/copter462_quad_first80k.bin"))
    assert f.diagnostics.skipped.get("record cut by the end of the file") == 1
    assert f.has("roll", "vx", "throttle")


def test_truncated_to_a_few_bytes(tmp_path):
    for rel in ("ardupilot/copter33_quad_log171.bin", "px4/x500_sitl_events.ulg",
                "mcap/sportcub_fixedwing_qualisys.mcap"):
        src = real_log(rel)
        p = tmp_path / ("tiny" + src.suffix)
        p.write_bytes(src.read_bytes()[:40])
        with pytest.raises(LogFormatError) as ei:
            read_flight(p)
        assert str(p) in str(ei.value)


def test_real_logs_folder_layout_known():
    if not REAL_LOGS.is_dir():
        pytest.skip("real logs absent")
    assert os.path.isdir(REAL_LOGS / "ardupilot")
