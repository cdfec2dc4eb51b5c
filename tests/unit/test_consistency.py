"""Convention checks (issue 41): a simulated flight in a format droneid writes (flat CSV), rewritten
the eight ways users get conventions wrong, is named in one line with a fix that works; the
conversions of the reader options are exact; the untouched sample logs raise nothing."""
from __future__ import annotations

import numpy as np
import pytest

from convention_rewrites import MISTAKES, reader_kwargs, rewrite_all
from droneid.logs.consistency import ConventionError, check_flight
from droneid.errors import ConfigError
from droneid.logs.flight import Flight, Provenance, Signal
from droneid.core.frames import euler_to_quat, quat_to_euler
from parsers import read_flight
from parsers._convention import convert, parse_factor

from conftest import SAMPLE_LOGS

SIM = SAMPLE_LOGS / "rotor_climb_eight.flat.csv"

#: mistake -> the finding's kind
KIND = {"ned": "ned", "frd": "frd", "ms": "time", "us": "time", "deg": "deg", "kmh": "kmh", "swap": "swap",
        "yaw": "yaw"}


@pytest.fixture(scope="module")
def rewritten(tmp_path_factory):
    return rewrite_all(SIM, tmp_path_factory.mktemp("rewrites"), "sim")


@pytest.mark.parametrize("mistake", sorted(MISTAKES))
def test_each_mistake_is_named_once_with_a_fix_that_works(rewritten, mistake):
    c = check_flight(read_flight(rewritten[mistake]))
    assert [f.kind for f in c.findings] == [KIND[mistake]], c.lines()
    line, = c.lines()
    assert line.startswith(str(rewritten[mistake]) + ": ") and "\n" not in line
    words = MISTAKES[mistake][1]
    assert " ".join(words).split(" --")[0] in c.findings[0].fix          # the fix the finding gives
    fixed = read_flight(rewritten[mistake], **reader_kwargs(words))
    assert check_flight(fixed).ok, check_flight(fixed).lines()
    orig = read_flight(SIM)
    for name in ("x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "yaw"):
        # the fix restores the flight as it was (to the CSV's printed precision)
        assert np.allclose(fixed[name].t, orig[name].t, atol=1e-6)
        assert np.allclose(np.unwrap(fixed[name].values), np.unwrap(orig[name].values), atol=1e-5), name


def test_the_sample_logs_as_written_raise_nothing():
    for p in sorted(SAMPLE_LOGS.glob("*.*")):
        if p.suffix in (".csv", ".mcap", ".tlog"):
            c = check_flight(read_flight(p))
            assert c.ok, c.lines()
            assert any(ch.status == "ok" for ch in c.checks), p


def test_identify_and_diagnose_refuse_before_any_fit(rewritten):
    from droneid.dataset.suitability import check_prior_data
    from priors.registry import prior_for
    flights = [read_flight(rewritten["kmh"]), read_flight(SIM)]
    prior, _ = prior_for("tilt-drag", set(flights[0].names))
    with pytest.raises(ConventionError) as e:
        check_prior_data(flights, prior, ("vx_dot", "vy_dot"), 0.05)
    assert len(e.value.lines) == 1 and "km/h" in e.value.lines[0] and str(rewritten["kmh"]) in e.value.lines[0]
    assert str(e.value).count("\n") == 1      # a head line, then one line per finding


def test_a_pose_only_log_in_milliseconds_is_named_by_its_accelerations(tmp_path):
    """No velocity or rates to compare: the horizontal acceleration, 1e-6 x g·tan(tilt) when the
    stamps are ms read as s, names the time unit."""
    import pandas as pd
    df = pd.read_csv(SIM)[["t", "x", "y", "z", "qw", "qx", "qy", "qz"]]
    df["t"] *= 1000
    p = tmp_path / "pose_ms.csv"
    df.to_csv(p, index=False)
    c = check_flight(read_flight(p))
    assert [(f.kind, f.fix) for f in c.findings] == [("time", "--time-unit ms")], c.lines()
    assert check_flight(read_flight(p, time_unit="ms")).ok


def test_a_delayed_velocity_is_measured_not_named(tmp_path):
    """vx logged 0.2 s late: the velocity check reports the lag (no reader option shifts one
    signal, so it is no finding)."""
    import pandas as pd
    df = pd.read_csv(SIM)
    df["vx"] = df["vx"].shift(4)           # 20 Hz: 0.2 s behind
    p = tmp_path / "late_vx.csv"
    df.dropna().to_csv(p, index=False)
    c = check_flight(read_flight(p))
    vel = next(ch for ch in c.checks if ch.name == "velocity vs position")
    assert vel.numbers["lag vx s"] == pytest.approx(0.2, abs=0.02)
    assert vel.numbers["lag vy s"] == pytest.approx(0.0, abs=0.02) and "0.2 s behind" in vel.detail


def test_an_frd_imu_is_named_as_one_frame_and_converted_back(tmp_path):
    """Rates AND accelerations in FRD (a whole FRD IMU): the gravity check sees az = -g, so the
    finding is --body-frame frd, which negates y and z of both."""
    import pandas as pd
    df = pd.read_csv(SIM)
    for c in ("wy", "wz", "ay", "az"):
        df[c] = -df[c]
    p = tmp_path / "frd_imu.csv"
    df.to_csv(p, index=False)
    c = check_flight(read_flight(p))
    assert [(f.kind, f.fix) for f in c.findings] == [("frd", "--body-frame frd")], c.lines()
    assert check_flight(read_flight(p, body_frame="frd")).ok


def _flight(t, **cols):
    sig = {k: Signal(k, t, v, "1", f"d/dt {k[1]}" if k in ("vx", "vy", "vz") else k) for k, v in cols.items()}
    return Flight(sig, Provenance(files=("f.csv",), format="csv"), segments={"armed": ((t[0], t[-1]),)})


def test_convert_ned_frd_time_and_scale_exactly():
    t = np.arange(0.0, 1.0, 0.1)
    one = np.ones_like(t)
    f = _flight(t, x=t, y=2 * t, z=3 * t, vx=one, vy=2 * one, vz=3 * one, wx=t, wy=t, wz=t, ax=t, ay=t, az=t)
    g = convert(f, world_frame="ned")
    assert np.allclose(g["x"].values, 2 * t) and np.allclose(g["y"].values, t) and np.allclose(g["z"].values, -3 * t)
    assert np.allclose(g["vx"].values, 2.0)           # derived velocity derived again from the new x
    h = convert(f, body_frame="frd")
    assert np.allclose(h["wx"].values, t) and np.allclose(h["wy"].values, -t) and np.allclose(h["az"].values, -t)
    k = convert(f, time_unit="ms")
    assert np.allclose(k["x"].t, t / 1000) and np.allclose(k.segments["armed"], [(0.0, t[-1] / 1000)])
    assert np.allclose(k["vx"].values, 1000.0)
    s = convert(f, scale={"wx": "pi/180", "ax": -1})
    assert np.allclose(s["wx"].values, np.radians(t)) and np.allclose(s["ax"].values, -t)
    assert any("--scale" in n for n in s.provenance.notes)
    assert convert(f) is f


def test_scaling_yaw_rebuilds_the_quaternion():
    t = np.arange(0.0, 1.0, 0.1)
    q = euler_to_quat(0.1 * t, 0.2 * t, 0.5 + t)
    f = _flight(t, **{n: q[:, i] for i, n in enumerate(("qw", "qx", "qy", "qz"))},
                roll=0.1 * t, pitch=0.2 * t, yaw=0.5 + t)
    g = convert(f, scale={"yaw": -1})
    r, p, y = quat_to_euler(np.column_stack([g[n].values for n in ("qw", "qx", "qy", "qz")]))
    assert np.allclose(y, -(0.5 + t)) and np.allclose(r, 0.1 * t) and np.allclose(p, 0.2 * t)
    assert np.allclose(g["yaw"].values, y)


@pytest.mark.parametrize("text, value", [("1/3.6", 1 / 3.6), ("pi/180", np.pi / 180), ("-1", -1.0),
                                         ("9.81", 9.81), ("1e-3", 1e-3), (2, 2.0)])
def test_parse_factor(text, value):
    assert parse_factor(text) == pytest.approx(value)


@pytest.mark.parametrize("bad", ["x", "0", "1/0", "", "3*2"])
def test_parse_factor_refuses(bad):
    with pytest.raises(ConfigError, match="--scale"):
        parse_factor(bad)


def test_scale_of_an_unknown_signal_is_refused():
    t = np.arange(0.0, 1.0, 0.1)
    with pytest.raises(ConfigError, match="did you mean 'vx'"):
        convert(_flight(t, x=t, vx=t), scale={"vxx": 2})


def test_checks_skip_with_a_reason_on_slow_or_missing_signals():
    t = np.arange(0.0, 60.0, 1.0)        # 1 Hz: too slow to differentiate the attitude
    f = _flight(t, x=np.sin(t), roll=0 * t, pitch=0 * t, yaw=0 * t, wx=0 * t, wy=0 * t, wz=0 * t)
    c = check_flight(f)
    assert c.ok
    by = {ch.name: ch for ch in c.checks}
    assert by["body rates vs attitude"].status == "skipped" and "Hz" in by["body rates vs attitude"].detail
    assert by["gravity in the accelerometer"].detail == "no accelerometer"


@pytest.mark.parametrize("mistake", ["ned", "frd", "kmh", "deg", "swap", "yaw"])
def test_the_mcap_and_tlog_writers_carry_a_mistake_the_fix_undoes(rewritten, tmp_path, mistake):
    """A mistaken flight written by droneid's MCAP and tlog writers: the same finding, and the
    same fix (the conversions are the reader boundary's, for every format); x/y swapped names no
    --column (these formats have no columns) but says where to fix it."""
    from parsers.mcap_writer import write_mcap
    from parsers.tlog_writer import write_tlog
    wrong = read_flight(rewritten[mistake])
    for write, ext in ((write_mcap, "mcap"), (write_tlog, "tlog")):
        p = tmp_path / f"{mistake}.{ext}"
        write(wrong, p)
        c = check_flight(read_flight(p))
        assert [f.kind for f in c.findings] == [KIND[mistake]], (ext, c.lines())
        if mistake == "swap":
            assert "no reader option" in c.findings[0].fix
        else:
            assert check_flight(read_flight(p, **reader_kwargs(MISTAKES[mistake][1]))).ok, ext


def test_noisy_positions_are_no_unit_mistake_but_a_velocity_in_kmh_still_is():
    """A position's derivative is noisy, and noise in it shrinks the fitted slope of v on dp/dt
    by r². A right vx with centimetres of position noise (a GPS-like track; a noise draw of the
    bench_commands vehicles) read "0.60 x d(x)/dt" at r 0.8: named a unit mistake and refused.
    The slope may lie anywhere in [s, s/r²] (forward and reverse regression), so a scale is named
    only when that whole range misses the right band; the same noisy flight with its velocity in
    km/h is still refused."""
    from droneid.logs.consistency import OK_SLOPE, _KMH, _may_be
    assert _may_be(0.59, 0.80, OK_SLOPE) and not _may_be(0.59, 1.0, OK_SLOPE)
    assert not _may_be(3.6, 0.95, OK_SLOPE) and not _may_be(1.944, 1.0, _KMH)   # knots stay knots
    from droneid.simulation.simulator import simulate
    f = simulate(path="random", duration_s=30.0, rate_hz=100.0, seed=0, pos_noise_m=0.032).flight
    vel = next(ch for ch in check_flight(f).checks if ch.name == "velocity vs position")
    assert vel.numbers["vx/dx"] < 0.75, vel.detail          # the dilution this test is about
    assert not check_flight(f).findings
    kmh = convert(f, scale={n: 3.6 for n in ("vx", "vy", "vz")})
    kinds = {x.kind for x in check_flight(kmh).findings}
    assert kinds and kinds <= {"kmh", "scale"}, check_flight(kmh).findings
