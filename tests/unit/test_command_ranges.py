"""Command normalisation is read from the range the values show, and stated (issue 29, item 11):
a Crazyflie-style 0..65535 PWM count is not taken for 1000-2000 µs, a range that fits nothing
known is kept as logged, and the source of the signal says what was seen and done."""
from __future__ import annotations

import numpy as np
import pytest

from parsers import read_flight
from parsers._build import command_to_unit


@pytest.mark.parametrize("values, scaled, said", [
    ([0.0, 0.25, 1.0], [0.0, 0.25, 1.0], "values 0..1: a 0..1 command, used as is"),
    ([0.0, 40.0, 100.0], [0.0, 0.4, 1.0], "values 0..100: percent, /100 -> 0..1"),
    ([0.0, 1100.0, 1900.0], [0.0, 0.1, 0.9], "values 0..1900: servo PWM 1000-2000 us"),
    ([0.0, 51.0, 255.0], [0.0, 0.2, 1.0], "values 0..255: 8-bit counts, /255 -> 0..1"),
    ([0.0, 26214.0, 65535.0], [0.0, 0.4, 1.0], "values 0..65535: 16-bit counts, /65535 -> 0..1"),
    ([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], "negative, no known command range; kept as logged"),
    ([0.0, 1e6], [0.0, 1e6], "no known command range"),
])
def test_range_decides_and_is_stated(values, scaled, said):
    v, how = command_to_unit(np.array(values))
    np.testing.assert_allclose(v, scaled, atol=1e-4)
    assert said in how


def test_crazyflie_pwm_counts_in_a_csv_are_counts_not_microseconds(tmp_path):
    """The issue's case: a motor column of 0..65535 counts was labelled "PWM 1000-2000 us" and
    scaled to 39..60; now it is 0..1 and the source says 16-bit counts."""
    t = np.arange(200) * 0.01
    pwm = np.round(20000 + 20000 * np.sin(t))           # 0..65535 counts, as the Crazyflie logs
    p = tmp_path / "cf.csv"
    p.write_text("t,x,y,z,motor_m1\n" + "".join(f"{a:.2f},0,0,1,{b:.0f}\n" for a, b in zip(t, pwm)))
    f = read_flight(p, column_map={"motor1": "motor_m1"})
    assert f["motor1"].values.max() <= 1.0 and f["motor1"].values.min() >= 0.0
    np.testing.assert_allclose(f["motor1"].values, pwm / 65535.0)
    assert "16-bit counts" in f["motor1"].source and "1000-2000" not in f["motor1"].source
    assert dict((n, s) for n, _, s in f.provenance.signal_sources)["motor1"] == f["motor1"].source


def test_a_throttle_column_is_normalised_by_its_range_too(tmp_path):
    p = tmp_path / "thr.csv"
    p.write_text("t,x,y,z,throttle\n" + "".join(f"{i * 0.01:.2f},0,0,1,{1000 + 5 * i}\n" for i in range(200)))
    f = read_flight(p)
    assert f["throttle"].values.max() <= 1.0 and "servo PWM" in f["throttle"].source
