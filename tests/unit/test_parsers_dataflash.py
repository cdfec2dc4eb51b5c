"""DataFlash reader on logs written here (4.x and 3.x field names): planted NED/FRD values come out
ENU/FLU, scalings (ThrOut 0..1000, centivolts, PWM), events and segments, truncation."""
from __future__ import annotations

import math

import numpy as np
import pytest

from parsers import detect_format, read_flight

from dataflash_fixture import DataFlashWriter


def _new_log(n=100, flip_at=None):
    w = DataFlashWriter()
    w.fmt("ATT", "QfffB", "TimeUS,Roll,Pitch,Yaw,AEKF")
    w.fmt("XKF1", "QBffffff", "TimeUS,C,VN,VE,VD,PN,PE,PD")
    w.fmt("IMU", "QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    w.fmt("RCOU", "QHHHHH", "TimeUS,C1,C2,C3,C4,C5")
    w.fmt("CTUN", "Qf", "TimeUS,ThO")
    w.fmt("BAT", "QBff", "TimeUS,Inst,Volt,Curr")
    w.fmt("EV", "QB", "TimeUS,Id")
    w.fmt("MODE", "QMB", "TimeUS,Mode,ModeNum")
    w.fmt("MSG", "QZ", "TimeUS,Message")
    w.add("MSG", 5_000_000, "ArduCopter V4.5.0 (abcdef12)")
    w.add("MSG", 5_000_000, "Frame: QUAD/X")
    w.add("MODE", 5_000_000, 5, 5)
    for i in range(n):
        tus = 5_000_000 + i * 100_000                      # boot clock starts at 5 s
        if i == 10:
            w.add("EV", tus, 10)                           # armed
        if i == 20:
            w.add("EV", tus, 28)                           # not landed (take-off)
        if i == 80:
            w.add("EV", tus, 18)                           # land complete
        if i == 90:
            w.add("EV", tus, 11)                           # disarmed
        roll = 190.0 if flip_at is not None and i >= flip_at else 10.0
        w.add("ATT", tus, roll, 20.0, 0.0, 3)              # deg; nose up 20, heading north
        w.add("XKF1", tus + 10, 0, 1.0, 0.5, -0.25, 0.1 * i, 0.0, -2.0)
        w.add("XKF1", tus + 10, 1, 9.0, 9.0, 9.0, 9.0, 9.0, 9.0)   # second core: ignored
        w.add("IMU", tus + 20, 0, 0.01, 0.02, 0.03, 0.1, 0.2, -9.8)
        w.add("RCOU", tus + 30, 1500, 1000, 2000, 1250, 0)
        w.add("CTUN", tus + 40, 0.45)
        w.add("BAT", tus + 50, 0, 15.2, 12.5)
    return w


def test_planted_frd_ned_values_come_out_flu_enu(tmp_path):
    p = tmp_path / "planted.bin"
    p.write_bytes(_new_log().bytes())
    assert detect_format(p) == "dataflash"
    f = read_flight(p)
    assert f.provenance.firmware == "ArduCopter V4.5.0 (abcdef12)" and f.provenance.vehicle == "quad/x"
    assert np.allclose(f["roll"].values, math.radians(10))
    assert np.allclose(f["pitch"].values, -math.radians(20))       # nose up -> negative pitch (FLU)
    assert np.allclose(f["yaw"].values, math.pi / 2)                # north -> +90 deg from east
    assert np.allclose(f["vx"].values, 0.5) and np.allclose(f["vy"].values, 1.0)   # core 0 only
    assert np.allclose(f["vz"].values, 0.25) and np.allclose(f["z"].values, 2.0)
    assert np.allclose(f["y"].values, 0.1 * np.arange(100), atol=1e-5)
    assert np.allclose(f["az"].values, 9.8, atol=1e-6) and np.allclose(f["ay"].values, -0.2)
    assert np.allclose(f["wy"].values, -0.02) and np.allclose(f["wz"].values, -0.03)
    assert np.allclose(f["motor1"].values, 0.5) and np.allclose(f["motor4"].values, 0.25)
    assert "motor5" not in f                                        # always 0: not an output
    assert np.allclose(f["throttle"].values, 0.45) and f["throttle"].source == "CTUN.ThO"
    assert np.allclose(f["battery_voltage"].values, 15.2, atol=1e-5)
    assert f["roll"].start_s == pytest.approx(0.0) and f["roll"].rate_hz == pytest.approx(10.0)
    assert f.segments["armed"] == ((1.0, 9.0),)
    assert f.segments["in_flight"] == ((2.0, 8.0),)
    kinds = [e.kind for e in f.events]
    assert kinds == ["mode", "armed", "takeoff", "land", "disarmed"]
    assert f.events[0].text == "LOITER"
    assert f.diagnostics.total_skipped == 0


def test_flip_over_is_a_crash_and_ends_the_flight(tmp_path):
    p = tmp_path / "flip.bin"
    p.write_bytes(_new_log(flip_at=50).bytes())
    f = read_flight(p)
    crash = [e for e in f.events if e.kind == "crash"]
    assert len(crash) == 1 and crash[0].t_s == pytest.approx(5.0)
    assert f.segments["in_flight"] == ((2.0, 5.0),)


def test_old_3x_names_and_scalings(tmp_path):
    w = DataFlashWriter()
    w.fmt("ATT", "IfffB", "TimeMS,Roll,Pitch,Yaw,X")
    w.fmt("EKF1", "Iffffff", "TimeMS,VN,VE,VD,PN,PE,PD")
    w.fmt("RCOU", "IHHHH", "TimeMS,Ch1,Ch2,Ch3,Ch4")
    w.fmt("CTUN", "Ih", "TimeMS,ThrOut")
    w.fmt("CURR", "Ihh", "TimeMS,Volt,Curr")
    w.fmt("GPS", "BIHBfLLeefI", "Status,TimeMS,Week,NSats,HDop,Lat,Lng,RelAlt,Alt,Spd,T")
    for i in range(50):
        ms = 1000 + 20 * i
        w.add("ATT", ms, -5.0, 0.0, 90.0, 0)              # heading east -> yaw 0
        w.add("EKF1", ms, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0)   # moving east
        w.add("RCOU", ms, 1100, 1100, 1100, 1100)
        w.add("CTUN", ms, 600)                              # 0..1000
        w.add("CURR", ms, 1650, 1234)                       # centivolts, centiamps
        w.add("GPS", 3 if i > 5 else 1, 123456789, 2000, 10, 0.9, -353632620, 1491652300, 100, 58400, 0.0, ms)
    p = tmp_path / "old.bin"
    p.write_bytes(w.bytes())
    f = read_flight(p)
    assert np.allclose(f["yaw"].values, 0.0, atol=1e-7) and np.allclose(f["roll"].values, math.radians(-5))
    assert np.allclose(f["vx"].values, 2.0) and np.allclose(f["vy"].values, 0.0)
    assert f["vx"].source == "EKF1.VN/VE/VD" and f["motor1"].source.startswith("RCOU.Ch1 (PWM 1000-2000 us")
    assert np.allclose(f["throttle"].values, 0.6) and f["throttle"].source == "CTUN.ThrOut / 1000"
    assert np.allclose(f["battery_voltage"].values, 16.5) and np.allclose(f["battery_current"].values, 12.34)
    assert np.allclose(f["lat"].values, -35.363262) and np.allclose(f["alt"].values, 584.0)
    assert f.diagnostics.skipped["GPS samples without a 3D fix"] == 6
    assert f["lat"].start_s == pytest.approx(f["roll"].t[6])     # GPS timed by T (boot ms), not GPS time
    assert f["roll"].start_s == 0.0


def test_cut_mid_record_reads_up_to_the_cut(tmp_path):
    data = _new_log().bytes()
    p = tmp_path / "cut.bin"
    p.write_bytes(data[: len(data) // 2 + 7])
    f = read_flight(p)
    assert f.diagnostics.skipped["record cut by the end of the file"] == 1
    assert 3.0 < f.duration_s < 6.0


def test_garbage_inside_is_skipped_and_counted(tmp_path):
    data = bytearray(_new_log().bytes())
    mid = len(data) // 2
    data[mid:mid] = bytes(range(40, 140))          # no 0xA3 0x95 in it
    p = tmp_path / "garbage.bin"
    p.write_bytes(bytes(data))
    f = read_flight(p)
    assert f.diagnostics.total_skipped >= 1
    assert f.duration_s > 9.0
