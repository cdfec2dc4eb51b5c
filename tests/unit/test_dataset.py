import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from droneid.dataset.builder import DatasetBuilder, resample_signal, subsample
from droneid.dataset.validation import split_by_flight, split_time_block
from droneid.errors import ConfigError, DataError, MissingSignalError
from droneid.logs.flight import Event, Flight, Signal
from droneid.core.frames import wrap_angle

from synth_flights import attitude, tilt_accel, tilt_drag_flight, tilt_drag_truth


@pytest.fixture(scope="module")
def flight():
    return tilt_drag_flight(duration_s=20.0)


def _target_err(ds, k_D=0.35):
    """RMS error of the target against the model on the dataset's own states."""
    ax, _ = tilt_accel(ds.t)
    return float(np.sqrt(np.mean((ds.y - (ax - k_D * ds.column("vx"))) ** 2)))


def test_each_differentiator_against_analytic_truth(flight):
    errs = {}
    for m in ("forward", "central", "savgol", "spline"):
        ds = DatasetBuilder(method=m).build(flight, "vx_dot")
        assert ds.input_names == ("vx", "pitch", "roll", "yaw")
        assert np.allclose(np.diff(ds.t), 0.05)
        errs[m] = _target_err(ds)
    # forward: O(Ts) bias; central: O(Ts²); smoothing ones at the native 100 Hz rate
    assert errs["forward"] < 0.08
    assert errs["central"] < 0.005
    assert errs["savgol"] < 0.02
    assert errs["spline"] < 0.01
    assert errs["central"] < errs["forward"] / 10


def test_forward_has_the_papers_indexing(flight):
    ds = DatasetBuilder(ts=0.05, method="forward", in_flight="all").build(flight, "vx_dot")
    vx = ds.column("vx")
    np.testing.assert_allclose(ds.y[:-1], np.diff(vx) / 0.05, rtol=1e-9, atol=1e-9)
    assert ds.t[-1] < 20.0 - 0.05 + 1e-9  # last grid sample has no successor: dropped
    assert any("forward difference has none" in n for n in ds.notes)


def test_smoothing_beats_forward_on_noisy_mocap():
    f = tilt_drag_flight(duration_s=20.0, noise=0.02, seed=3)
    fwd = _target_err(DatasetBuilder(method="forward").build(f, "vx_dot"))
    sg = _target_err(DatasetBuilder(method="savgol").build(f, "vx_dot"))
    sp = _target_err(DatasetBuilder(method="spline", window_s=0.5).build(f, "vx_dot"))
    assert sg < 0.5 * fwd and sp < 0.5 * fwd, (fwd, sg, sp)


def test_yaw_crossing_pi_interpolates_correctly(flight):
    ds = DatasetBuilder(ts=0.033, method="central").build(flight, "vx_dot")
    yaw = ds.column("yaw")
    truth = wrap_angle(attitude(ds.t)[2])
    d = np.abs(wrap_angle(yaw - truth))
    assert d.max() < 1e-4
    assert yaw.min() >= -np.pi and yaw.max() < np.pi
    assert np.sum(np.abs(np.diff(yaw)) > np.pi) >= 2  # it did cross ±pi


@settings(max_examples=40, deadline=None)
@given(a=st.floats(-3, 3).filter(lambda v: abs(v) > 0.05), b=st.floats(-3, 3),
       frac=st.lists(st.floats(0, 1), min_size=1, max_size=20))
def test_resampling_angles_property(a, b, frac):
    t = np.linspace(0, 10, 201)
    s = Signal("yaw", t, wrap_angle(a * t + b), "rad")
    tq = 10 * np.asarray(frac)
    got = resample_signal(s, tq)
    assert np.all(np.abs(wrap_angle(got - (a * tq + b))) < 1e-9)
    assert np.all(got >= -np.pi) and np.all(got < np.pi)


@settings(max_examples=40, deadline=None)
@given(a=st.floats(-100, 100), b=st.floats(-100, 100),
       frac=st.lists(st.floats(0, 1), min_size=1, max_size=20))
def test_resampling_linear_signals_is_exact_and_nan_outside(a, b, frac):
    t = np.cumsum(np.r_[0.0, np.linspace(0.01, 0.05, 50)])
    s = Signal("vx", t, a * t + b, "m/s")
    tq = t[-1] * np.asarray(frac)
    np.testing.assert_allclose(resample_signal(s, tq), a * tq + b, atol=1e-9 * (1 + abs(a) + abs(b)))
    assert np.isnan(resample_signal(s, np.array([-1.0, t[-1] + 1]))).all()


def test_quaternion_only_attitude_gives_consistent_euler():
    f = tilt_drag_flight(duration_s=10.0, names=("vx", "vy"), quaternion=True)
    ds = DatasetBuilder(method="central").build(f, "vx_dot", extras=("qw", "qx", "qy", "qz"))
    from synth_flights import attitude
    roll, pitch, yaw = attitude(ds.t)
    np.testing.assert_allclose(ds.column("pitch"), pitch, atol=1e-4)
    np.testing.assert_allclose(ds.column("roll"), roll, atol=1e-4)
    assert np.abs(wrap_angle(ds.column("yaw") - yaw)).max() < 1e-4
    q = np.column_stack([ds.column(n) for n in ("qw", "qx", "qy", "qz")])
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    assert any("derived from the attitude quaternion" in n for n in ds.notes)


def test_target_from_positions_when_velocity_is_absent():
    f = tilt_drag_flight(duration_s=10.0, names=("x", "y", "z", "roll", "pitch", "yaw"))
    ds = DatasetBuilder(method="central").build(f, "vx_dot")
    truth = tilt_drag_truth(np.arange(0, 10.0, 0.01))
    vx_true = np.interp(ds.t, np.arange(0, 10.0, 0.01), truth["vx"])
    y_true = np.interp(ds.t, np.arange(0, 10.0, 0.01), truth["vx_dot"])
    assert np.sqrt(np.mean((ds.column("vx") - vx_true) ** 2)) < 0.01
    assert np.sqrt(np.mean((ds.y - y_true)[2:-2] ** 2)) < 0.02
    assert any("vx (the target) derived from x" in n and "twice" in n for n in ds.notes)
    ds_f = DatasetBuilder(method="forward").build(f, "vx_dot")
    assert len(ds_f) == len(ds) - 2  # forward twice: the last two grid samples have no target


def test_in_flight_detection_trims_ground_and_crash():
    t = np.arange(0.0, 40.0, 0.01)
    up = (t > 5) & (t < 30)
    z = np.where(up, 1.0, 0.0) + 0.002 * np.sin(40 * t)
    vx = np.where(up, 0.5 * np.sin(t), 0.0)
    thr = np.where(up, 0.5, 0.05)
    tilt = np.where(t > 35, 1.6, 0.05 * np.sin(t))  # lies on its side from 35 s
    tilt = np.where((t > 12) & (t < 12.15), 1.3, tilt)  # a short aggressive 75 deg excursion
    sig = {"z": z, "vx": vx, "vy": 0 * t, "vz": 0 * t, "throttle": thr, "pitch": tilt,
           "roll": 0 * t, "yaw": 0 * t}
    f = Flight({k: Signal(k, t, v, "rad" if k in ("pitch", "roll", "yaw") else "m") for k, v in sig.items()})
    ds = DatasetBuilder().build(f, "vx_dot")
    assert 4.9 < ds.t.min() < 5.3 and 29.7 < ds.t.max() < 30.1
    assert any("ground detected from height and power or speed" in n for n in ds.notes)
    # the crash after landing is outside the airborne part: no crash note; now airborne crash:
    sig["z"] = np.where(t > 5, 1.0, 0.0)
    sig["throttle"] = np.where(t > 5, 0.5, 0.05)
    f2 = Flight({k: Signal(k, t, v, "rad" if k in ("pitch", "roll", "yaw") else "m") for k, v in sig.items()})
    ds2 = DatasetBuilder().build(f2, "vx_dot")
    assert ds2.t.max() < 34.6
    assert ds2.t.max() > 34.0
    assert any("crash trimmed" in n for n in ds2.notes)
    ds3 = DatasetBuilder(in_flight="all").build(f2, "vx_dot")
    assert ds3.t.min() == 0.0 and ds3.t.max() > 39.0


def test_ground_contact_is_trimmed_inside_the_logs_flying_segment():
    """A log's "flying" flag (the Crazyflie's is_flying) is set while the vehicle still sits on
    the ground spinning its motors up: there the ground, not the thrust, holds it (v̇z = 0 at
    hover power), so those samples are not free flight and must not reach the fit."""
    t = np.arange(0.0, 20.0, 0.01)
    up = (t > 4) & (t < 16)
    z = np.where(up, 1.0, 0.02)
    thr = np.where(t > 2, 0.5, 0.1)  # full hover power on the ground from 2 s to lift-off at 4 s
    sig = {"z": z, "vx": np.where(up, 0.3 * np.sin(t), 0.0), "vy": 0 * t, "vz": 0 * t,
           "throttle": thr, "pitch": 0.05 * np.sin(t), "roll": 0 * t, "yaw": 0 * t}
    f = Flight({k: Signal(k, t, v, "rad" if k in ("pitch", "roll", "yaw") else "m") for k, v in sig.items()},
               segments={"in_flight": ((2.0, 18.0),)})
    b = DatasetBuilder()
    ds = b.build(f, "vx_dot")
    margin = b.ground_margin_s
    assert 4.0 + margin - 0.06 <= ds.t.min() <= 4.0 + margin + 0.06
    # the grid step and the forward difference's dropped last sample: up to two steps earlier
    assert 16.0 - margin - 2 * b.ts - 0.01 <= ds.t.max() <= 16.0 - margin + 0.01
    assert any("in-flight part from the log's segments" in n for n in ds.notes)
    assert any("ground detected from height and power or speed" in n for n in ds.notes)
    # without the margin, the data reach lift-off and touchdown
    ds0 = DatasetBuilder(ground_margin_s=0.0).build(f, "vx_dot")
    assert ds0.t.min() < ds.t.min() - 0.1 and ds0.t.max() > ds.t.max() + 0.1


def test_segments_events_and_time_windows_are_used(flight):
    f = Flight(flight.signals, flight.provenance, segments={"in_flight": ((2.0, 15.0),),
                                                            "armed": ((1.0, 14.0),)},
               events=(Event(12.0, "crash", "impact"),))
    ds = DatasetBuilder().build(f, "vx_dot")
    assert ds.t.min() == pytest.approx(2.0) and ds.t.max() <= 11.5
    ds = DatasetBuilder(time_windows=[(3.0, 6.0), (8.0, 9.0)]).build(f, "vx_dot")
    assert ds.t.min() == pytest.approx(3.0) and ds.t.max() < 9.0
    assert not np.any((ds.t > 6.0) & (ds.t < 8.0))


def test_gaps_split_the_data_and_are_not_differenced_across(flight):
    s = flight["vx"]
    keep = (s.t < 5.0) | (s.t > 6.0)
    f = flight.with_signals(Signal("vx", s.t[keep], s.values[keep], "m/s"))
    ds = DatasetBuilder(method="forward").build(f, "vx_dot")
    assert not np.any((ds.t > 5.0) & (ds.t < 6.0))
    assert _target_err(ds) < 0.08


def test_several_flights_sources_and_splits(flight):
    f2 = tilt_drag_flight(duration_s=10.0, label="other")
    ds = DatasetBuilder().build([flight, f2], "vy_dot", extras=("z", "vz"))
    assert ds.sources == ("synthetic", "other")
    assert set(np.unique(ds.flight)) == {0, 1}
    assert set(ds.extra) == {"z", "vz"} and ds.input_names == ("vy", "pitch", "roll", "yaw")
    tr, te = split_time_block(ds, 0.3)
    assert len(tr) + len(te) == len(ds)
    for k in (0, 1):
        assert tr.t[tr.flight == k].max() < te.t[te.flight == k].min()
    tr, te = split_time_block(ds, 0.2, block="middle")
    assert te.t[te.flight == 0].min() > tr.t[tr.flight == 0].min()
    assert te.t[te.flight == 0].max() < tr.t[tr.flight == 0].max()
    tr, te = split_by_flight(ds, "other")
    assert set(te.flight) == {1} and set(tr.flight) == {0}
    sub = subsample(ds, 100, seed=1)
    assert len(sub) == 100 and np.all(np.diff(sub.t[sub.flight == 0]) > 0)
    assert np.array_equal(subsample(ds, 100, seed=1).y, sub.y)
    assert subsample(ds, 10 ** 6) is ds


def test_default_extras_are_every_canonical_signal(flight):
    ds = DatasetBuilder().build(flight, "vx_dot")
    assert set(ds.extra) == {"vy", "vz", "x", "y", "z"}
    ds = DatasetBuilder().build(flight, "vz_dot")  # no throttle in the flight: left out
    assert ds.input_names == ("vz", "roll", "pitch")
    assert DatasetBuilder().build(flight, "vx_dot", extras=()).extra == {}


def test_errors(flight):
    with pytest.raises(ConfigError, match="did you mean 'savgol'"):
        DatasetBuilder(method="savgl").build(flight)
    with pytest.raises(ConfigError, match="window_s"):
        DatasetBuilder(method="forward", window_s=0.3).build(flight)
    with pytest.raises(ConfigError, match="'ts'"):
        DatasetBuilder(ts=0).build(flight)
    with pytest.raises(ConfigError, match="in_flight"):
        DatasetBuilder(in_flight="air").build(flight)
    with pytest.raises(ConfigError, match="time window"):
        DatasetBuilder(time_windows=[(5, 2)]).build(flight)
    with pytest.raises(MissingSignalError, match="throttle"):
        DatasetBuilder().build(flight, "vx_dot", inputs=["vx", "throttle"])
    with pytest.raises(MissingSignalError, match="did you mean 'pitch'"):
        DatasetBuilder().build(flight, "vx_dot", inputs="vx,pich")
    with pytest.raises(ConfigError, match="no default inputs"):
        DatasetBuilder().build(flight, "wz_dot")
    with pytest.raises(DataError, match="no samples"):
        DatasetBuilder(time_windows=[(100, 200)]).build(flight)
    with pytest.raises(ConfigError, match="test_fraction"):
        split_time_block(DatasetBuilder().build(flight), 1.5)


def test_other_derivative_targets(flight):
    ds = DatasetBuilder(method="central").build(flight, "yaw_dot", inputs=["vx"])
    truth = 0.4 + 0.54 * np.cos(0.9 * ds.t) + 0.111 * np.cos(0.37 * ds.t)
    np.testing.assert_allclose(ds.y, truth, atol=1e-3)  # unwrapped before differencing


def test_span_ending_a_hair_below_a_grid_point_keeps_its_last_sample():
    """A log whose time stamps end at 12.7999999999 s (float round-off of 12.8) must still build
    with the central differentiator (the grid must not step past the signal's end)."""
    from droneid.dataset.builder import DatasetBuilder
    from droneid.logs.flight import Flight, Signal
    t = np.arange(257) * 0.05
    t[-1] = 12.799999999999999
    sig = {n: Signal(n, t, v, u) for n, v, u in [
        ("vx", np.sin(t), "m/s"), ("vy", np.cos(t), "m/s"), ("roll", 0 * t, "rad"),
        ("pitch", 0.1 * np.sin(t), "rad"), ("yaw", 0 * t, "rad")]}
    f = Flight(sig, segments={"in_flight": [(0.0, t[-1])], "armed": [(0.0, t[-1])]})
    ds = DatasetBuilder(method="central", in_flight="all").build([f], target="vx_dot")
    assert np.all(np.isfinite(ds.y)) and ds.t[-1] <= t[-1]
