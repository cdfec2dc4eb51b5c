"""Damaged real logs (moved from tests/unit/test_parsers_detect.py): a real file's magic bytes
followed by noise, truncated copies, the real DataFlash prefix cut mid-record. Skipped where
../shared/real_logs is absent."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.errors import LogFormatError
from parsers import read_flight

from conftest import real_log

pytestmark = pytest.mark.real_logs


@pytest.mark.parametrize("rel", ["ardupilot/copter33_quad_log171.bin", "mavlink/copter357_quad_mission1.tlog",
                                 "px4/x500_sitl_events.ulg", "mcap/sportcub_fixedwing_qualisys.mcap",
                                 "px4/octo_px4tools_01_07_59.px4log"])
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
                                       ("px4/x500_sitl_events.ulg", 0.5),
                                       ("px4/octo_px4tools_01_07_59.px4log", 0.5)])
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
    if src.suffix in (".bin", ".px4log", ".tlog", ".mcap"):
        assert f.diagnostics.total_skipped >= 1 or f.diagnostics.warnings


def test_real_80k_dataflash_prefix_is_flagged_as_cut():
    f = read_flight(real_log("ardupilot/copter462_quad_first80k.bin"))
    assert f.diagnostics.skipped.get("record cut by the end of the file") == 1
    assert f.has("roll", "vx", "throttle")


def test_truncated_to_a_few_bytes(tmp_path):
    for rel in ("ardupilot/copter33_quad_log171.bin", "px4/x500_sitl_events.ulg",
                "mcap/sportcub_fixedwing_qualisys.mcap", "px4/octo_px4tools_01_07_59.px4log"):
        src = real_log(rel)
        p = tmp_path / ("tiny" + src.suffix)
        p.write_bytes(src.read_bytes()[:40])
        with pytest.raises(LogFormatError) as ei:
            read_flight(p)
        assert str(p) in str(ei.value)


def test_real_logs_folder_layout_known(real_logs):
    assert (real_logs / "ardupilot").is_dir()
