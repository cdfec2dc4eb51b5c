"""Rotor signals (issue 11): rpm1..16 (rpm), motor1..16 (0..1), throttle (0..1), thrust (N),
battery_voltage (V) from every format, pinned against planted truth (units, motor order,
normalisation), written and read back by the project's writers. Listed for the real logs:
tests/real_logs/test_rotor_signals_real.py."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from droneid.cli import main
from droneid.errors import ConfigError
from droneid.logs.flight import Flight, Signal, canonical_unit, is_canonical
from parsers import read_flight

from dataflash_fixture import DataFlashWriter
from tlog_fixture import tlog_bytes


def test_rotor_names_are_canonical():
    assert is_canonical("rpm1") and is_canonical("rpm16") and not is_canonical("rpm17")
    assert canonical_unit("rpm7") == "rpm" and canonical_unit("motor3") == "1"


# ------------------------------------------------------------------------------ DataFlash
def _dataflash(path, params, n=20):
    w = DataFlashWriter()
    w.fmt("PARM", "QNf", "TimeUS,Name,Value")
    w.fmt("ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw")
    w.fmt("RCOU", "QHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6")
    w.fmt("ESC", "QBffff", "TimeUS,Instance,RPM,RawRPM,Volt,Curr")          # ArduPilot 4.x layout
    for k, v in params.items():
        w.add("PARM", 0, k, float(v))
    for i in range(n):
        tu = 1_000_000 + 20_000 * i
        w.add("ATT", tu, 0.0, 0.0, 0.0)
        # channel c carries 1100 + 100 c + i µs; channel 6 is a camera servo
        w.add("RCOU", tu, *[1100 + 100 * c + i for c in range(1, 6)], 1500)
        for inst in range(4):
            w.add("ESC", tu + 1000 * inst, inst, 1000 * (inst + 1) + i, 0.0, 12.0, 1.0)
    path.write_bytes(w.bytes())
    return path


def test_dataflash_servo_functions_pwm_range_and_esc_rpm(tmp_path):
    # channel 1 drives motor 3, channel 2 motor 1, channel 3 motor 4, channel 4 motor 2,
    # channel 5 motor 5 (SERVO function 37); channel 6 is not a motor
    params = {"SERVO1_FUNCTION": 35, "SERVO2_FUNCTION": 33, "SERVO3_FUNCTION": 36,
              "SERVO4_FUNCTION": 34, "SERVO5_FUNCTION": 37, "SERVO6_FUNCTION": 6,
              "MOT_PWM_MIN": 1100, "MOT_PWM_MAX": 1900}
    f = read_flight(_dataflash(tmp_path / "a.bin", params))
    motor_of_channel = {1: 3, 2: 1, 3: 4, 4: 2, 5: 5}
    for ch, motor in motor_of_channel.items():
        s = f[f"motor{motor}"]
        pwm = 1100 + 100 * ch + np.arange(20)
        np.testing.assert_allclose(s.values, np.clip((pwm - 1100) / 800, 0, 1), atol=1e-12)
        assert s.source.startswith(f"RCOU.C{ch} (PWM 1100-1900 us (MOT_PWM_MIN/MAX)"), s.source
    assert "motor6" not in f
    for inst in range(4):
        s = f[f"rpm{inst + 1}"]
        assert s.unit == "rpm"
        np.testing.assert_allclose(s.values, 1000 * (inst + 1) + np.arange(20))


def test_dataflash_without_servo_functions_is_a_quad_on_channels_1_to_4(tmp_path):
    f = read_flight(_dataflash(tmp_path / "b.bin", {"SERVO1_MIN": 1000}))
    assert [n for n in f.names if n.startswith("motor")] == ["motor1", "motor2", "motor3", "motor4"]
    assert "no SERVOn_FUNCTION" in f["motor2"].source and "1000-2000" in f["motor2"].source
    np.testing.assert_allclose(f["motor2"].values, (1300 + np.arange(20) - 1000) / 1000)


# ------------------------------------------------------------------------------ tlog
def _param(name, value):
    return ("param_value", 0.0, dict(param_id=name.encode(), param_value=float(value), param_type=9,
                                     param_count=1, param_index=0))


def test_tlog_servo_output_params_esc_telemetry_and_thrust(tmp_path):
    msgs = [("heartbeat", 0.0, {}), _param("SERVO1_FUNCTION", 34), _param("SERVO2_FUNCTION", 33),
            _param("SERVO3_FUNCTION", 0), _param("SERVO1_MIN", 1000), _param("SERVO1_MAX", 2000),
            _param("MOT_PWM_MIN", 1200), _param("MOT_PWM_MAX", 1800)]
    for i in range(10):
        t = 0.1 + 0.1 * i
        msgs.append(("servo_output_raw", t, dict(time_usec=i, port=0, servo1_raw=1200 + 60 * i,
                                                 servo2_raw=1500, servo3_raw=1700, servo4_raw=0,
                                                 servo5_raw=0, servo6_raw=0, servo7_raw=0, servo8_raw=0)))
        msgs.append(("esc_telemetry_1_to_4", t + 0.01, dict(
            temperature=[0] * 4, voltage=[0] * 4, current=[0] * 4, totalcurrent=[0] * 4,
            rpm=[5000 + i, 6000 + i, 7000 + i, 8000 + i], count=[0] * 4)))
        msgs.append(("attitude_target", t + 0.02, dict(
            time_boot_ms=i, type_mask=0, q=[1, 0, 0, 0], body_roll_rate=0, body_pitch_rate=0,
            body_yaw_rate=0, thrust=0.05 * i)))
    p = tmp_path / "a.tlog"
    p.write_bytes(tlog_bytes(msgs))
    f = read_flight(p)
    np.testing.assert_allclose(f["motor2"].values, (1200 + 60 * np.arange(10) - 1200) / 600)  # ch1
    np.testing.assert_allclose(f["motor1"].values, 0.5)                                        # ch2
    assert "motor3" not in f and "motor4" not in f       # ch3 is not a motor; nothing on motor 4
    for k in range(4):
        np.testing.assert_allclose(f[f"rpm{k + 1}"].values, 5000 + 1000 * k + np.arange(10))
        assert f[f"rpm{k + 1}"].unit == "rpm"
    np.testing.assert_allclose(f["throttle"].values[1:], 0.05 * np.arange(1, 10), atol=1e-6)
    assert f["throttle"].source.startswith("ATTITUDE_TARGET.thrust")


# ------------------------------------------------------------------------------ flat CSV
def _csv(tmp_path, header, rows, name="f.csv"):
    p = tmp_path / name
    p.write_text(",".join(header) + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    return p


def test_csv_spellings_units_and_ranges(tmp_path):
    t = np.arange(10) * 0.01
    header = ["time", "x", "m1_erpm", "rpm_2", "motor_rpm_3", "esc_rpm4", "m1_thrust", "motor2",
              "m3", "motor4", "thrust", "battery_V"]
    rows = [(ti, 0.1 * i, 30000 + i, 2000 + i, 3000 + i, 4000 + i, 0.1 * (i % 5),
             1000 + 100 * i, 5 * i, 0.5, 0.05 * i, 12.0 - 0.1 * i) for i, ti in enumerate(t)]
    f = read_flight(_csv(tmp_path, header, rows))
    np.testing.assert_allclose(f["rpm1"].values, 30000 + np.arange(10))
    assert "electrical rpm" in f["rpm1"].source and f["rpm1"].unit == "erpm"        # issue 29
    for k in (2, 3, 4):
        np.testing.assert_allclose(f[f"rpm{k}"].values, 1000 * k + np.arange(10))
        assert "electrical" not in f[f"rpm{k}"].source
    np.testing.assert_allclose(f["motor1"].values, 0.1 * (np.arange(10) % 5))
    np.testing.assert_allclose(f["motor2"].values, np.clip(np.arange(10) / 10, 0, 1))   # PWM
    assert "PWM 1000-2000" in f["motor2"].source
    np.testing.assert_allclose(f["motor3"].values, 0.05 * np.arange(10))                 # percent
    np.testing.assert_allclose(f["throttle"].values, 0.05 * np.arange(10))              # 0..1 thrust
    assert "thrust" not in f
    np.testing.assert_allclose(f["battery_voltage"].values, 12.0 - 0.1 * np.arange(10))


def test_csv_thrust_in_newtons_and_percent_throttle(tmp_path):
    rows = [(0.01 * i, 0.3 + 0.01 * i, 2.0 + i, 40 + i) for i in range(10)]
    f = read_flight(_csv(tmp_path, ["t", "x", "thrust_cmd_N", "throttle_pct"], rows))
    assert f["thrust"].unit == "N"
    np.testing.assert_allclose(f["thrust"].values, 2.0 + np.arange(10))
    np.testing.assert_allclose(f["throttle"].values, (40 + np.arange(10)) / 100)
    g = read_flight(_csv(tmp_path, ["t", "x", "thrust"], [(0.01 * i, 0, 3.0 + i) for i in range(10)], "g.csv"))
    assert g["thrust"].unit == "N" and "throttle" not in g


def test_column_option_maps_other_names(tmp_path, capsys):
    rows = [(0.01 * i, 0.1 * i, 7000 + i) for i in range(10)]
    p = _csv(tmp_path, ["t", "x", "ESC_A"], rows)
    f = read_flight(p, column_map={"rpm3": "ESC_A"})
    np.testing.assert_allclose(f["rpm3"].values, 7000 + np.arange(10))
    with pytest.raises(ConfigError, match="not a canonical signal"):
        read_flight(p, column_map={"rpmm3": "ESC_A"})
    assert main(["inspect", str(p), "--column", "rpm3=ESC_A"]) == 0
    assert "rpm3" in capsys.readouterr().out


# ------------------------------------------------------------------------------ ULog
def _ulog(params, outputs, esc_rpm, controls=None) -> bytes:
    def msg(typ, body):
        return struct.pack("<HB", len(body), ord(typ)) + body

    def param(name, value):
        key = f"int32_t {name}".encode()
        return msg("P", bytes([len(key)]) + key + struct.pack("<i", value))
    out = bytearray(b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 0))
    out += msg("F", b"actuator_outputs:uint64_t timestamp;uint32_t noutputs;float[4] output;")
    out += msg("F", b"esc_report:int32_t esc_rpm;float esc_voltage;")
    out += msg("F", b"esc_status:uint64_t timestamp;uint8_t esc_count;esc_report[4] esc;")
    out += msg("F", b"actuator_motors:uint64_t timestamp;float[4] control;")
    for k, v in params.items():
        out += param(k, v)
    out += msg("A", struct.pack("<BH", 0, 1) + b"actuator_outputs")
    out += msg("A", struct.pack("<BH", 0, 2) + b"esc_status")
    if controls is not None:
        out += msg("A", struct.pack("<BH", 0, 3) + b"actuator_motors")
    for i in range(len(outputs)):
        ts = 100_000 + 10_000 * i
        out += msg("D", struct.pack("<HQI4f", 1, ts, 4, *outputs[i]))
        out += msg("D", struct.pack("<HQB", 2, ts + 100, 4)
                   + b"".join(struct.pack("<if", r, 12.0) for r in esc_rpm[i]))
        if controls is not None:
            out += msg("D", struct.pack("<HQ4f", 3, ts + 200, *controls[i]))
    return bytes(out)


def test_ulog_esc_rpm_and_pwm_range_from_params(tmp_path):
    n = 8
    outputs = [(1100 + 10 * i, 1500, 1900, 0) for i in range(n)]
    rpm = [(1000 + i, -2000 - i, 3000, 0) for i in range(n)]       # reversed motor: negative rpm
    p = tmp_path / "a.ulg"
    p.write_bytes(_ulog({"PWM_MAIN_MIN": 1100, "PWM_MAIN_MAX": 1900, "PWM_MAIN_MIN3": 1500}, outputs, rpm))
    f = read_flight(p)
    np.testing.assert_allclose(f["motor1"].values, (10 * np.arange(n)) / 800, atol=1e-9)
    np.testing.assert_allclose(f["motor2"].values, 0.5)
    np.testing.assert_allclose(f["motor3"].values, 1.0)              # (1900 - 1500) / (1900 - 1500)
    assert "PWM_MAIN_MIN3" in f["motor3"].source and "motor4" not in f
    np.testing.assert_allclose(f["rpm1"].values, 1000 + np.arange(n))
    np.testing.assert_allclose(f["rpm2"].values, 2000 + np.arange(n))
    assert "rpm4" not in f and f["rpm1"].unit == "rpm"


def test_ulog_actuator_motors_win_and_reversible_range_is_normalised(tmp_path):
    n = 6
    controls = [(0.1 * i, -1.0 + 0.2 * i, 0.5, 0.0) for i in range(n)]
    p = tmp_path / "b.ulg"
    p.write_bytes(_ulog({}, [(1500, 1500, 1500, 1500)] * n, [(0, 0, 0, 0)] * n, controls))
    f = read_flight(p)
    np.testing.assert_allclose(f["motor1"].values, 0.1 * np.arange(n), atol=1e-7)
    np.testing.assert_allclose(f["motor2"].values, (0.2 * np.arange(n)) / 2, atol=1e-7)   # -1..1
    assert "-1..1 -> 0..1" in f["motor2"].source
    assert not any(k.startswith("rpm") for k in f.names)


# ------------------------------------------------------------------------------ writers
@pytest.fixture
def rotor_flight():
    t = np.arange(40) * 0.05
    sig = [Signal("x", t, np.sin(t), "m"), Signal("y", t, np.cos(t), "m"), Signal("z", t, 1 + t, "m"),
           Signal("roll", t, 0.1 * t, "rad"), Signal("pitch", t, -0.1 * t, "rad"),
           Signal("yaw", t, 0.2 * t, "rad")]
    for k in range(1, 5):
        sig.append(Signal(f"motor{k}", t, 0.2 + 0.1 * k + 0.01 * np.sin(t), "1"))
        sig.append(Signal(f"rpm{k}", t + 0.01, 10000 + 1000 * k + 100 * np.round(np.sin(t), 2), "rpm"))
    return Flight({s.name: s for s in sig})


@pytest.mark.parametrize("fmt", ["tlog", "mcap", "csv"])
def test_writers_carry_motor_commands_and_speeds(rotor_flight, tmp_path, fmt):
    from parsers.csv_writer import write_flat_csv
    from parsers.mcap_writer import write_mcap
    from parsers.tlog_writer import write_tlog
    write = {"tlog": write_tlog, "mcap": write_mcap, "csv": write_flat_csv}[fmt]
    g = read_flight(write(rotor_flight, tmp_path / f"r.{fmt}"))
    tol = {"tlog": (1e-3, 0.5), "mcap": (1e-6, 1e-3), "csv": (1e-8, 1e-4)}[fmt]
    for k in range(1, 5):
        m, r = rotor_flight[f"motor{k}"], rotor_flight[f"rpm{k}"]
        np.testing.assert_allclose(np.interp(m.t, g[f"motor{k}"].t, g[f"motor{k}"].values), m.values,
                                   atol=tol[0], err_msg=f"motor{k}")
        gr = g[f"rpm{k}"]
        assert gr.unit == "rpm"
        inside = (gr.t >= r.start_s - 1e-9) & (gr.t <= r.end_s + 1e-9)   # CSV: one time base
        assert inside.sum() >= len(r) - 1
        np.testing.assert_allclose(gr.values[inside], np.interp(gr.t[inside], r.t, r.values),
                                   atol=tol[1], err_msg=f"rpm{k}")


def test_mcap_topic_override_maps_a_topic_element_to_a_signal(rotor_flight, tmp_path):
    from parsers.mcap_writer import write_mcap
    p = write_mcap(rotor_flight, tmp_path / "r.mcap")
    g = read_flight(p, topics={"throttle": "/drone/motors[1]", "rpm9": "/drone/rpm2"})
    np.testing.assert_allclose(g["throttle"].values, rotor_flight["motor2"].values, atol=1e-6)
    assert g["throttle"].source.startswith("/drone/motors data[1] (values ")
    assert g["throttle"].source.endswith(": a 0..1 command, used as is)")
    np.testing.assert_allclose(g["rpm9"].values, rotor_flight["rpm2"].values, rtol=1e-6)
    with pytest.raises(ConfigError, match="unknown MCAP topic role"):
        read_flight(p, topics={"thrtle": "/drone/motors[1]"})


def test_tlog_writer_maps_more_than_four_motors(tmp_path):
    from parsers.tlog_writer import write_tlog
    t = np.arange(10) * 0.1
    sig = {f"motor{k}": Signal(f"motor{k}", t, 0.1 * k + 0 * t, "1") for k in range(1, 7)}
    sig["roll"] = Signal("roll", t, 0 * t, "rad")
    sig["pitch"] = Signal("pitch", t, 0 * t, "rad")
    sig["yaw"] = Signal("yaw", t, 0 * t, "rad")
    g = read_flight(write_tlog(Flight(sig), tmp_path / "hexa.tlog"))
    for k in range(1, 7):
        np.testing.assert_allclose(g[f"motor{k}"].values, 0.1 * k, atol=1e-3)
        assert f"SERVO{k}_FUNCTION" in g[f"motor{k}"].source
