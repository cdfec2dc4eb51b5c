import re

import numpy as np
import pytest

from droneid.dataset.align import estimate_clock_offset, merge_flights
from droneid.dataset.builder import DatasetBuilder
from droneid.errors import DataError, MissingSignalError

from synth_flights import tilt_drag_flight


@pytest.fixture(scope="module")
def pair():
    # mocap-like: positions + quaternion at 100 Hz with mm noise; autopilot-like: velocities and
    # Euler angles at 50 Hz on a clock 0.37 s behind, recorded over a different span
    mocap = tilt_drag_flight(duration_s=25.0, rate_hz=100.0, noise=0.01, seed=1,
                             names=("x", "y", "z"), quaternion=True, label="mocap")
    ap = tilt_drag_flight(duration_s=30.0, rate_hz=50.0, noise=0.02, seed=2, clock_shift_s=0.37,
                          names=("vx", "vy", "vz", "roll", "pitch", "yaw"), label="autopilot")
    return mocap, ap.between(-0.37 + 3.0, 40.0)


@pytest.mark.parametrize("signal", ["auto", "speed", "vz", "yaw_rate"])
def test_planted_clock_offset_is_found_within_a_sample(pair, signal):
    mocap, ap = pair
    off = estimate_clock_offset(mocap, ap, signal=signal)
    assert off == pytest.approx(0.37, abs=0.01), off  # one 100 Hz sample
    back = estimate_clock_offset(ap, mocap, signal=signal)
    assert back == pytest.approx(-0.37, abs=0.01)


def test_subsample_refinement_beats_the_grid(pair):
    mocap, ap = pair
    off = estimate_clock_offset(mocap, ap, signal="speed", dt_s=0.05)
    assert abs(off - 0.37) < 0.02  # grid step 0.05 s, nearest grid lag would be 0.35 or 0.40


def test_merge_then_build(pair):
    mocap, ap = pair
    merged = merge_flights(mocap, ap)
    assert {"x", "qw", "vx", "yaw"} <= set(merged.names)
    assert merged["vx"].t[0] == pytest.approx(3.0, abs=0.01)  # back on the mocap clock
    assert any(re.search(r"clock offset \+0\.3[67]", n) for n in merged.provenance.notes)
    assert merged.provenance.files == ("mocap.csv", "autopilot.csv")
    ds = DatasetBuilder(method="central").build(merged, "vx_dot")
    from synth_flights import tilt_accel
    ax, _ = tilt_accel(ds.t)
    err = np.sqrt(np.mean((ds.y - (ax - 0.35 * ds.column("vx"))) ** 2))
    assert err < 0.5  # 50 Hz noisy velocities, central differences at 20 Hz
    # a given offset is used as is; clashing names keep the primary's
    m2 = merge_flights(ap, mocap.with_signals(ap["yaw"]), offset_s=-0.37)
    assert m2["yaw"] is ap["yaw"]
    assert any("kept from autopilot: yaw" in n for n in m2.provenance.notes)


def test_alignment_errors(pair):
    mocap, ap = pair
    with pytest.raises(MissingSignalError, match="throttle"):
        estimate_clock_offset(mocap, ap, signal="throttle")
    with pytest.raises(DataError, match="no common signal"):
        estimate_clock_offset(mocap.without("x", "y", "z", "qw", "qx", "qy", "qz").with_signals(mocap["x"]),
                              ap)
