"""predict --open-loop (issue 28 item 3): the nanodrone benchmark's metric from the command line,
with the planted rotor-thrust truth of a simulated flight as the final models."""
from __future__ import annotations

import json

import pytest
import sympy as sp

from droneid.cli import main
from droneid.fitting.closed_form import IdentifiedModel
from droneid.simulation.simulator import simulate


@pytest.mark.slow
def test_open_loop_scores_the_final_model_nominal_physics_and_the_held_state(tmp_path, capsys):
    sim = simulate(path="eight", duration_s=12.0, rate_hz=100.0, seed=3,
                   effects={"thrust_variation": {"amp_m": 0.3, "period_s": 2.5}})
    k_T = sim.truth["rotors"]["k_T"]            # m/s² per (10⁴ rpm)²
    kd = sim.truth["params"]["k_drag"]
    r, p, y, = (sp.Symbol(n) for n in ("roll", "pitch", "yaw"))
    w = sum(sp.Symbol(f"rpm{i}") ** 2 for i in range(1, 5)) * k_T * 1e-8
    bz = {"x": sp.cos(y) * sp.sin(p) * sp.cos(r) + sp.sin(y) * sp.sin(r),
          "y": sp.sin(y) * sp.sin(p) * sp.cos(r) - sp.cos(y) * sp.sin(r),
          "z": sp.cos(p) * sp.cos(r)}
    finals = {f"v{a}_dot": IdentifiedModel(f"v{a}_dot", w * bz[a] - kd * sp.Symbol(f"v{a}") - (9.81 if a == "z" else 0),
                                           {}, "planted").to_dict() for a in "xyz"}
    result = tmp_path / "result.json"
    result.write_text(json.dumps({"schema": "droneid.identify/2", "config": {
        "prior_used": "rotor-thrust", "prior_params": {"source": "rpm", "k_T": k_T}, "ts": 0.05, "method": "central"},
        "targets": {t: {"final": m} for t, m in finals.items()}}))
    assert main(["-q", "simulate", "--path", "eight", "--duration", "12", "--seed", "3", "--effect",
                 "thrust_variation=0.3,2.5", "-o", str(tmp_path)]) == 0   # the same flight, as a log
    log = tmp_path / "sim_eight_s3.mcap"
    capsys.readouterr()
    assert main(["predict", str(result), str(log), "--open-loop", "--json"]) == 0
    ol = json.loads(capsys.readouterr().out)["open_loop"]
    assert list(ol) == ["identified", "nominal physics", "constant"]
    for per in ol.values():
        assert set(per) == {"1", "10", "50", "simerr"}
        assert set(per["simerr"]) == {"position", "velocity", "attitude", "rates"}
    # the planted truth beats holding the state on position and velocity, and has drag that the
    # nominal physics lacks
    assert ol["identified"]["simerr"]["velocity"] < ol["constant"]["simerr"]["velocity"]
    assert ol["identified"]["simerr"]["velocity"] <= ol["nominal physics"]["simerr"]["velocity"]
    # both keep the logged rates: the same attitude and rates error
    assert ol["identified"]["simerr"]["rates"] == pytest.approx(ol["nominal physics"]["simerr"]["rates"])
