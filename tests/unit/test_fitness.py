"""droneid.dataset.suitability.assess (issue 13): planted flights with known rates, airborne time, vehicle
type and excitation; the inspect block. The verdicts on the shared real logs:
tests/real_logs/test_fitness_real.py."""
from __future__ import annotations

import json
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from droneid.cli import main
from droneid.dataset.builder import DatasetBuilder
from droneid.errors import ConfigError, DataError
from droneid.dataset.suitability import (MIN_AIRBORNE_S, TILT_DRAG_SIGNALS, assess)
from droneid.logs.flight import Flight, Provenance, Signal
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
    # the grid samples a forward-difference dataset keeps: the builder's own count
    assert f.samples == math.floor(f.airborne_s / 0.05 + 1e-9) == \
        len(DatasetBuilder(ts=0.05).build(_flight(), "vx_dot", inputs=TILT_DRAG_SIGNALS[2:]))
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
           "droneid has no built-in fixed-wing model" in a.problems[0]
    assert a.problems[0].endswith("pass --vehicle multirotor to override")
    with pytest.raises(DataError, match="fixed-wing"):
        a.raise_if_refused()
    assert _assess(_flight(vehicle="fixed-wing"), vehicle="multirotor").ok
    rover = _assess(_flight(vehicle="rover"))
    assert not rover.ok


def test_unknown_and_vtol_vehicles_are_warnings():
    a = _assess(_flight(vehicle="unknown", declared=None))
    assert a.ok and any("vehicle type not declared" in w and "--vehicle" in w for w in a.warnings)
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


def test_an_optional_signal_s_rate_is_said_never_refused():
    """A command prior's battery voltage is used by the thrust curve where it helps: log171's
    9.9 Hz voltage was missing from the 'logged slower than the grid' note (walkthrough)."""
    f = _flight()
    for hz in (10.0, 1.0):      # coarse; and below 1/(4 Ts), where a needed signal is refused
        t = np.arange(0.0, 30.0, 1 / hz)
        g = Flight({**f.signals, "battery_voltage": Signal("battery_voltage", t, 12.0 + 0 * t, "V")},
                   f.provenance, segments=f.segments)
        a = _assess(g, optional_signals=("battery_voltage",))
        assert a.ok and not a.problems
        assert any("slower than the grid" in w and f"battery_voltage {hz:.1f} Hz" in w for w in a.warnings)
        assert not any("battery_voltage" in w for w in _assess(g).warnings)


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


def _kinematic(kind: str, duration=40.0, rate=100.0) -> Flight:
    """An undeclared vehicle flying east with yaw 0: 10 s of hover, then vx = 3 sin(0.8 t).
    ``multirotor``: pitch = atan(ax / g) (a multirotor tilts the way it accelerates), level hover;
    ``bird``: the same motion, its attitude swinging by 20-25 deg whatever it accelerates (flaps,
    perches); ``windy``: a multirotor leaning 15 deg into a steady wind throughout (not a mismatch);
    ``fixed-wing``: never slower than 6 m/s, pitch a few degrees whatever the acceleration."""
    t = np.arange(0, duration, 1 / rate)
    moving = t >= 10.0
    vx = np.where(moving, 3.0 * np.sin(0.8 * (t - 10.0)), 0.0)
    ax = np.where(moving, 2.4 * np.cos(0.8 * (t - 10.0)), 0.0)
    pitch = np.arctan(ax / 9.81)
    roll = 0 * t
    if kind == "bird":
        pitch = np.radians(25.0) * np.sin(1.3 * t + 1.0)
        roll = np.radians(20.0) * np.sin(0.7 * t)
    if kind == "windy":
        pitch = np.arctan(ax / 9.81 + np.tan(np.radians(15.0)))
    if kind == "fixed-wing":
        vx = 8.0 + 2.0 * np.sin(0.6 * t)
        pitch = np.radians(3.0) + 0 * t
    zero = 0 * t
    sig = [Signal("roll", t, roll, "rad"), Signal("pitch", t, pitch, "rad"),
           Signal("yaw", t, zero, "rad"), Signal("vx", t, vx, "m/s"),
           Signal("vy", t, zero, "m/s"), Signal("vz", t, zero, "m/s"), Signal("z", t, 2 + zero, "m")]
    prov = Provenance(files=(f"{kind}.csv",), format="csv")
    return Flight({s.name: s for s in sig}, prov, segments={"in_flight": ((0.0, duration),)})


def test_undeclared_vehicle_is_judged_from_its_data():
    ok = _assess(_kinematic("multirotor"))
    ev = ok.flights[0].vehicle
    assert ok.ok and ev.looks == "multirotor", (ok.problems, ev)
    assert ev.hover_s == pytest.approx(10.0, abs=0.5) and ev.hover_tilt_deg < 0.5 and ev.tilt_mismatch_deg < 1
    assert any("look like a multirotor" in w for w in ok.warnings)
    windy = _assess(_kinematic("windy")).flights[0].vehicle        # a steady lean is no mismatch
    assert windy.looks == "multirotor" and windy.hover_tilt_deg > 14 and windy.tilt_mismatch_deg < 1, windy
    for kind, why in (("bird", "its tilt does not follow its acceleration"), ("fixed-wing", "never hovers")):
        a = _assess(_kinematic(kind))
        assert not a.ok and a.flights[0].vehicle.looks == "not a multirotor"
        assert why in a.problems[0] and "pass --vehicle multirotor" in a.problems[0], a.problems
        assert "\n" not in a.problems[0]
        assert _assess(_kinematic(kind), vehicle="multirotor").ok        # the override
        assert _assess(_kinematic(kind)).to_dict()["flights"][0]["vehicle_evidence"]["looks"] == "not a multirotor"


def test_problems_are_ordered_from_the_most_fundamental():
    """never airborne, then no valid state estimate, then missing signals, then rates; the
    mapping hint fits the format (no --column / --topic for a ULog)."""
    from droneid.logs.flight import Diagnostics
    f = _flight(armed=False, vel_rate=1.0).without("vx")
    f = replace(f, provenance=replace(f.provenance, format="ulog"),
                diagnostics=Diagnostics({"vehicle_local_position samples with v_xy_valid false": 9}))
    p = _assess(f).problems
    assert "no airborne data" in p[0] and "no valid state estimate" in p[1]
    assert any("logged at 1.0 Hz" in x for x in p[2:])
    assert not any("--column" in x or "--topic" in x for x in p)
    g = _flight().without("yaw")
    assert "--column yaw=COLUMN" in _assess(g).problems[0]
    mcap = replace(g, provenance=replace(g.provenance, format="mcap"))
    assert "--topic yaw=TOPIC" in _assess(mcap).problems[0]
    uf = replace(g, provenance=replace(g.provenance, format="ulog"))
    hint = _assess(uf).problems[0].split("missing")[1]
    assert "--column" not in hint and "--topic" not in hint


def test_rates_and_samples_are_gap_aware():
    """A signal in bursts: its rate is per second of data, and only the bursts count as samples
    (a 100 Hz signal logged 2 s out of every 20 s is 100 Hz over 20 % of the time, not 100 Hz over
    all of it)."""
    from droneid.dataset.suitability import coverage
    f = _flight(duration=60.0)
    keep = (f["vx"].t % 20.0) < 2.0
    bursty = Signal("vx", f["vx"].t[keep], f["vx"].values[keep], "m/s")
    c = coverage(bursty)
    assert len(c.bursts) == 3 and c.existence_s == pytest.approx(6.0, abs=0.05)
    assert c.rate_hz == pytest.approx(100.0, rel=0.01) and "3 bursts: 0.0-2.0 s, 20.0-22.0 s" in c.describe()
    a = _assess(f.with_signals(bursty))
    assert a.flights[0].airborne_s == pytest.approx(6.0, abs=0.1)
    assert a.flights[0].samples == len(DatasetBuilder(ts=0.05).build(f.with_signals(bursty), "vx_dot",
                                                                      inputs=TILT_DRAG_SIGNALS[2:]))
    assert any("vx comes in 3 bursts" in w for w in a.warnings)
    # bursts of samples 7 ms apart, one burst every 0.25 s: 4 samples per second, not 143
    t = np.concatenate([k * 0.25 + np.arange(4) * 0.007 for k in range(400)])
    mav = Signal("vx", t, np.sin(t), "m/s")
    assert 1 / np.median(np.diff(t)) > 100                            # what a median step says
    assert mav.rate_hz == coverage(mav).rate_hz == pytest.approx(16.0, rel=0.02)


def test_damaged_huge_values_raise_no_numpy_warning():
    """Issue 29: "overflow encountered in square" leaked from mutated MCAPs; 1e308 in a signal
    (a flipped exponent bit) must end up non-finite, not as a warning."""
    import warnings
    t = np.arange(0, 20, 0.01)
    v = np.sin(t)
    v[500], v[501] = 1e308, -1e308
    sig = [Signal(n, t, v.copy(), "rad" if n in ("roll", "pitch", "yaw") else "m/s")
           for n in ("vx", "vy", "vz", "roll", "pitch", "yaw")]
    f = Flight({s.name: s for s in sig}, Provenance(files=("h.csv",), format="csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = _assess(f)
    json.dumps(a.to_dict())


def test_undeclared_vehicle_types_are_one_line_naming_the_flights():
    """The crazyflie squares printed seven lines "vehicle type not declared" (one per flight)
    before the first verdict; predict printed them on stdout."""
    flights = []
    for k in range(1, 4):
        f = _flight(vehicle="unknown", declared=None)
        flights.append(replace(f, provenance=replace(f.provenance, files=(f"square_run{k}.csv",))))
    a = _assess(flights)
    lines = [w for w in a.warnings if "vehicle type not declared" in w]
    assert len(lines) == 1, a.warnings
    assert "3 flights (square_run1, square_run2, square_run3)" in lines[0] and "--vehicle" in lines[0]
    assert len(a.undeclared) == 3


def test_identify_says_undeclared_vehicles_once_over_training_and_test_flights():
    from droneid.identify.pipeline import _data_notes
    from droneid.core.text import undeclared_line
    def fitness(names):
        und = tuple((n, "the data look like a multirotor (x)", "the data look like a multirotor") for n in names)
        return SimpleNamespace(undeclared=und, warnings=(undeclared_line(list(und)),
                                                         "melon_run1: tilt varies by 1 deg only"))
    mk = fitness
    notes = _data_notes({"train": mk(["square_run1", "square_run2"]), "test": mk(["melon_run1"])})
    assert sum("vehicle type not declared" in n for n in notes) == 1, notes
    assert "square_run1, square_run2, melon_run1" in notes[0]
    assert "data (test): melon_run1: tilt varies by 1 deg only" in notes
