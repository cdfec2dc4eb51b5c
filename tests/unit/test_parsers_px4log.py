"""PX4 sdlog2 (.px4log) reader on logs written here as sdlog2 writes them: planted NED/FRD values
come out ENU/FLU as the ULog reader's would, time from the TIME records, PWM outputs, STAT
segments, format detection beside ArduPilot DataFlash. Damaged sdlog2 logs (cut, garbage, no TIME
record): tests/integration/test_fuzz_parsers.py."""
from __future__ import annotations

import math

import numpy as np
import pytest

from droneid.errors import LogFormatError
from droneid.core.frames import euler_to_quat
from parsers import detect_format, read_flight

from dataflash_fixture import DataFlashWriter, sdlog2_log

N = 100


def _write(tmp_path, w, name="log.px4log"):
    p = tmp_path / name
    p.write_bytes(w.bytes())
    return p


def test_planted_frd_ned_values_come_out_flu_enu(tmp_path):
    p = _write(tmp_path, sdlog2_log())
    assert detect_format(p) == "px4log"
    f = read_flight(p)
    assert f.provenance.format == "px4log"
    # time: TIME.StartTime µs minus the first, one record per 0.1 s cycle
    np.testing.assert_allclose(f["roll"].t, np.arange(N) * 0.1, atol=1e-9)
    # Euler (the quaternion is not filled in): roll kept, pitch negated, yaw north -> pi/2
    assert np.allclose(f["roll"].values, 0.1) and np.allclose(f["pitch"].values, -0.2)
    assert np.allclose(f["yaw"].values, math.pi / 2)
    assert not f.has("qw")
    # body rates and specific force FRD -> FLU
    assert np.allclose(f["wx"].values, 0.01) and np.allclose(f["wy"].values, -0.02)
    assert np.allclose(f["wz"].values, -0.03)
    assert np.allclose(f["az"].values, 9.8) and np.allclose(f["ay"].values, -0.2)
    # NED position and velocity -> ENU
    assert np.allclose(f["vx"].values, 0.5) and np.allclose(f["vy"].values, 1.0)
    assert np.allclose(f["vz"].values, 0.25) and np.allclose(f["z"].values, 2.0)
    np.testing.assert_allclose(f["y"].values, 0.1 * np.arange(N))
    # PWM outputs, standard range; an output never driven is no motor
    assert [round(float(f[f"motor{k}"].values[0]), 3) for k in (1, 2, 3, 4)] == [0.5, 0.0, 1.0, 0.25]
    assert not f.has("motor5")
    assert "PWM 1000-2000 us" in f["motor1"].source
    assert np.allclose(f["throttle"].values, 0.45) and np.allclose(f["battery_voltage"].values, 22.2)
    # STAT: armed 1..9 s, in flight 2..8 s, mode names from pymavlink
    assert f.segments["armed"] == ((1.0, 9.0),)
    assert f.segments["in_flight"] == ((2.0, 8.0),)
    assert [e.text for e in f.events if e.kind == "mode"] == ["MANUAL", "AUTO_MISSION"]
    assert f.provenance.vehicle_type == "multirotor" and f.provenance.vehicle == "octorotor on PX4FMU_V2"
    assert f.provenance.firmware == "PX4 (44d2c4a1)"


def test_a_filled_quaternion_gives_the_same_attitude_as_the_ulog_reader(tmp_path):
    f = read_flight(_write(tmp_path, sdlog2_log(q_frd_ned=euler_to_quat(0.1, 0.2, 0.0))))
    assert f.has("qw", "qx", "qy", "qz")
    assert np.allclose(f["roll"].values, 0.1) and np.allclose(f["pitch"].values, -0.2)
    assert np.allclose(f["yaw"].values, math.pi / 2)


def test_lpos_samples_flagged_invalid_are_skipped_and_counted(tmp_path):
    # PFlg 0b1101 on every tenth sample: z invalid (bit 2), the rest valid
    f = read_flight(_write(tmp_path, sdlog2_log(pflg=0b1101)))
    assert f.diagnostics.skipped["LPOS samples whose PFlg marks Z invalid"] == N // 10
    assert len(f["z"]) == N - N // 10 and len(f["x"]) == N and len(f["vz"]) == N


def test_ardupilot_dataflash_is_not_taken_for_a_px4log(tmp_path):
    w = DataFlashWriter()
    w.fmt("ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw")
    w.add("ATT", 1_000_000, 1.0, 2.0, 3.0)
    assert detect_format(_write(tmp_path, w, "a.bin")) == "dataflash"
    # the same records as sdlog2 writes them, but stamped with TimeUS: ArduPilot's
    w2 = DataFlashWriter(sdlog2=True)
    w2.fmt("ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw")
    w2.add("ATT", 1_000_000, 1.0, 2.0, 3.0)
    assert detect_format(_write(tmp_path, w2, "b.bin")) == "dataflash"


def test_a_log_without_time_records_is_refused_naming_the_file(tmp_path):
    w = sdlog2_log(n=0)
    p = _write(tmp_path, w, "formats_only.px4log")
    with pytest.raises(LogFormatError, match=r"formats_only\.px4log: no TIME records"):
        read_flight(p)
