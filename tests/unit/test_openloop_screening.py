"""The open-loop metric's windows: airborne stretches clear of gaps and screened glitches, the
rule of the datasets and of the multi-step prediction (droneid.simulation.openloop.flight_state_logs)."""
import numpy as np

from droneid.logs.flight import Signal
from droneid.simulation.openloop import flight_state_logs
from droneid.simulation.simulator import simulate


def test_a_motor_speed_glitch_splits_the_stretch_and_no_window_crosses_it():
    flight = simulate(path="circle", duration_s=12, seed=4).flight
    clean = flight_state_logs([flight])
    rpm = flight["rpm2"]
    v = rpm.values.copy()
    i = int(np.searchsorted(rpm.t, 6.0))
    v[i] = 40 * np.nanmax(v)           # one impossible sample, 40x the motors' maximum
    glitched = flight_state_logs([flight.with_signals(Signal("rpm2", rpm.t, v, rpm.unit, rpm.source))])
    assert len(glitched) == len(clean) + 1
    t_glitch = rpm.t[i]
    for log in glitched:
        assert not (log.t_s[0] <= t_glitch <= log.t_s[-1])
        assert np.all(log.rpm < 10 * np.nanmax(rpm.values))
    assert all(log.name == flight.name for log in glitched)   # one validation block per flight


def test_every_stretch_is_on_one_grid_step_so_windows_can_be_pooled():
    """Two flights whose stamps differ in step (jitter, another logger): every stretch is put on
    the median step of all of them, and open_loop pools them without refusing."""
    from dataclasses import replace as dc_replace
    from droneid.simulation.openloop import Constant, open_loop
    a = simulate(path="circle", duration_s=6, seed=1).flight
    b = simulate(path="circle", duration_s=6, seed=2, rate_hz=99.0).flight
    b = dc_replace(b, provenance=dc_replace(b.provenance, files=("other.csv",)))
    logs = flight_state_logs([a, b])
    assert len({round(log.dt_s, 12) for log in logs}) == 1
    assert open_loop({"constant": Constant()}, logs)["constant"].windows > 0
