"""droneid.fitness.assess (issue 13): planted flights with known rates, airborne time, vehicle
type and excitation; the inspect block. The verdicts on the shared real logs:
tests/real_logs/test_fitness_real.py."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from droneid.cli import main
from droneid.errors import ConfigError, DataError
from droneid.fitness import (MIN_AIRBORNE_S, TILT_DRAG_SIGNALS, assess)
from droneid.flight import Flight, Provenance, Signal
from parsers import read_flight


def _flight(duration=30.0, rate=100.0, vel_rate=None, vehicle="multirotor", declared="test",
            armed=True, tilt_deg=10.0, speed=3.0, yaw_deg=90.0) -> Flight:
    t = np.arange(0, duration, 1 / rate)
    tv = np.arange(0, duration, 1 / (vel_rate or rate))
    w = 2 * np.pi / 10
    sig = [
        Signal("roll", t, np.radians(tilt_deg) * np.sin(w * t), "rad"),
        Signal("pitch", t, np.radians(tilt_deg) * np.cos(w * t) * 0.5, "rad"),
        Signal("yaw", t, np.radians(yaw_deg) * t / duration, "rad"),
        Signal("vx", tv, speed * (0.5 + 0.5 * np.sin(w * tv)), "m/s"),
        Signal("vy", tv, 0 * tv, "m/s"),
        Signal("z", t, 2 + 0 * t, "m"),
    ]
    seg = {"armed": ((0.0, duration),) if armed else (), "in_flight": ((0.0, duration),) if armed else ()}
    prov = Provenance(files=("planted.csv",), format="csv", vehicle_type=vehicle, vehicle_declared=declared)
    return Flight({s.name: s for s in sig}, prov, segments=seg)


def _assess(f, ts=0.05, **kw):
    return assess(f, needed_signals=TILT_DRAG_SIGNALS, ts=ts, **kw)


def test_a_good_flight_passes_with_its_measurements():
    a = _assess(_flight())
    assert a.ok and not a.problems and not a.warnings, (a.problems, a.warnings)
    f = a.flights[0]
    assert f.airborne_s == pytest.approx(29.99, abs=0.02)
    assert f.samples == math.floor(f.airborne_s / 0.05) + 1
    assert f.rates_hz["vx"] == pytest.approx(100.0)
    assert f.tilt_deg[1] == pytest.approx(10.0, abs=0.05)            # max(|roll|, |pitch|)
    assert f.speed_ms[1] == pytest.approx(3.0, abs=0.01) and f.speed_ms[0] == pytest.approx(0.0, abs=0.01)
    assert f.yaw_span_deg == pytest.approx(90.0, abs=0.1)
    a.raise_if_refused()
    json.dumps(a.to_dict())


def test_fixed_wing_log_is_refused_unless_overridden():
    a = _assess(_flight(vehicle="fixed-wing", declared="HEARTBEAT type MAV_TYPE_FIXED_WING (1)"))
    assert not a.ok
    assert "multirotor (quadrotor) prior on a fixed-wing log (HEARTBEAT type MAV_TYPE_FIXED_WING (1)): " \
           "pass --vehicle multirotor to override" in a.problems[0]
    with pytest.raises(DataError, match="fixed-wing"):
        a.raise_if_refused()
    assert _assess(_flight(vehicle="fixed-wing"), vehicle="multirotor").ok
    rover = _assess(_flight(vehicle="rover"))
    assert not rover.ok


def test_unknown_and_vtol_vehicles_are_warnings():
    a = _assess(_flight(vehicle="unknown", declared=None))
    assert a.ok and any("vehicle type unknown" in w and "--vehicle" in w for w in a.warnings)
    v = _assess(_flight(vehicle="vtol"))
    assert v.ok and any("vtol" in w and "hover" in w for w in v.warnings)


def test_slow_velocity_is_refused_and_a_coarser_grid_accepts_it():
    f = _flight(vel_rate=1.0)
    a = _assess(f)
    assert not a.ok
    p = next(p for p in a.problems if "vx" in p)
    assert "vx is logged at 1.0 Hz, below 1/(4 Ts) = 5 Hz for Ts = 0.05 s" in p and "--ts 0.25" in p
    b = _assess(f, ts=0.25)
    assert b.ok and any("barely resolves" in w or "barely" in w for w in b.warnings)


def test_rate_between_quarter_and_one_grid_step_is_a_warning():
    a = _assess(_flight(vel_rate=10.0))
    assert a.ok
    assert any("slower than the grid" in w and "vx 10.0 Hz" in w for w in a.warnings)


def test_no_airborne_time_and_short_flights():
    a = _assess(_flight(armed=False))
    assert not a.ok and any("no airborne data" in p and "never armed" in p for p in a.problems)
    b = _assess(_flight(duration=5.0))
    assert b.ok and any(f"< {MIN_AIRBORNE_S:.0f} s" in w for w in b.warnings)


def test_little_excitation_and_missing_signals():
    a = _assess(_flight(tilt_deg=1.0, speed=0.2, yaw_deg=5.0))
    text = " ".join(a.warnings)
    assert a.ok and "tilt varies" in text and "horizontal speed varies" in text and "yaw spans" in text
    f = _flight()
    b = _assess(f.without("vy"))
    assert not b.ok and "signal 'vy' is missing" in b.problems[0]


def test_bad_arguments():
    with pytest.raises(ConfigError):
        _assess(_flight(), vehicle="plane")
    with pytest.raises(DataError):
        _assess(_flight(), ts=0)


def test_user_vehicle_on_read_flight(tmp_path):
    p = tmp_path / "f.csv"
    p.write_text("t,x,y,z\n" + "".join(f"{i * 0.1},{i},0,1\n" for i in range(20)))
    f = read_flight(p)
    assert f.provenance.vehicle_type == "unknown" and f.provenance.vehicle_declared is None
    g = read_flight(p, vehicle="fixed-wing")
    assert g.provenance.vehicle_type == "fixed-wing" and g.provenance.vehicle_declared == "--vehicle fixed-wing"
    with pytest.raises(ConfigError, match="vehicle"):
        read_flight(p, vehicle="plane")


def test_inspect_reports_the_declared_vehicle_type(tmp_path, capsys):
    from parsers.tlog_writer import write_tlog
    f = _flight()
    f = replace(f, provenance=Provenance())
    p = write_tlog(f.with_signals(Signal("x", f["z"].t, 0 * f["z"].t, "m"),
                                  Signal("y", f["z"].t, 0 * f["z"].t, "m")), tmp_path / "a.tlog")
    assert main(["inspect", str(p)]) == 0
    out = capsys.readouterr().out
    assert "type:      multirotor (from HEARTBEAT type MAV_TYPE_QUADROTOR (2))" in out


def test_a_flight_spanning_days_is_not_scanned():
    f = _flight()
    late = Signal("z", np.array([0.0, 1.0, 5e6]), np.array([1.0, 1.0, 1.0]), "m")
    a = _assess(f.with_signals(late))
    assert not a.ok and any("not a flight (damaged time stamps?)" in p for p in a.problems)
