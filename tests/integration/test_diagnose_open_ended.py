"""The open-ended SNGP search on the residual: reported only when it passes the held-out test."""
from __future__ import annotations

import numpy as np
import pytest

import diag_synth as S
from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose_datasets
from droneid.diagnosis.residual_search import clock_like

CFG = DiagnoseConfig(generations=1500, population_size=200, seed=3)


@pytest.mark.slow
def test_open_ended_search_claims_nothing_on_a_control_flight():
    for seed in (1, 2):
        r = diagnose_datasets(S.make(None, seed=seed, duration_s=40),
                              S.make(None, seed=seed + 50, phase=1.0, duration_s=40),
                              prior=S.TiltDragStub(), config=CFG)
        for t, o in r.open_ended.items():
            assert o["ran"] and o["equation"], t
            assert not o["passed"], (t, o["equation"], o["evidence"])
        assert "open-ended search found" not in r.conclusion


def test_clock_like_signals_are_kept_out_of_the_search():
    t = np.arange(0, 60, 0.05)
    f = np.zeros(t.size, int)
    assert clock_like(16.0 - 0.01 * t + 0.001 * np.sin(t), t, f)
    assert not clock_like(np.sin(0.5 * t), t, f)
    r = diagnose_datasets(S.make(None, seed=0, duration_s=30), None, prior=S.TiltDragStub(), config=CFG)
    assert "battery_voltage" not in r.open_ended["vx_dot"]["signals"]
    assert "yaw" in r.open_ended["vx_dot"]["signals"]
