"""identify's rotational stage (droneid.rotation.stage): what it chooses on, what it says, and
that its record reads back."""
import math

import numpy as np
import pytest

from droneid.errors import DataError
from droneid.fitting.verdict import axis_verdict
from droneid.rotation.stage import AxisResult, RotationResult, choose_rotation, speed_scale


def test_axis_verdict_needs_validation_and_test_alike():
    held = axis_verdict("wx_dot", "held", 60.0, 60.0, math.nan, math.nan)
    assert held.kind == "no better" and "held" in held.text
    better = axis_verdict("wx_dot", "damping", 60.0, 20.0, 16.0, 10.0)
    assert better.kind == "better" and "38 %" in better.text
    worse = axis_verdict("wy_dot", "torque", 58.0, 21.0, 18.0, 41.6)
    assert worse.kind == "worse" and "WORSE" in worse.text and "torque model" in worse.text
    # without test flights the validation decides, and says where it was measured
    v = axis_verdict("wz_dot", "torque", 5.5, 4.6, math.nan, math.nan)
    assert v.kind == "better" and "held-out training flights" in v.text
    assert axis_verdict("wz_dot", "torque", 5.5, 5.4, 6.6, 6.5).kind == "no better"
    # better on the test flights but not in validation: no better, and it says so
    lucky = axis_verdict("wx_dot", "damping", 60.0, 59.0, 16.0, 12.0)
    assert lucky.kind == "no better" and "not in validation" in lucky.text
    # an error that cannot be measured gives no verdict, never a "+nan %"
    assert axis_verdict("wx_dot", "damping", 0.0, 0.0, math.nan, math.nan).kind == "no verdict"
    # worse without test flights says so without blaming test flights
    held_out = axis_verdict("wx_dot", "damping", 10.0, 12.0, math.nan, math.nan)
    assert held_out.kind == "worse" and "test flights" not in held_out.text


def test_speed_scale_follows_the_recorded_unit():
    from droneid.simulation.simulator import simulate
    flight = simulate(path="circle", duration_s=3, seed=1).flight
    scale, why = speed_scale(flight)
    assert scale == pytest.approx(2 * math.pi / 60) and "rpm" in why
    with pytest.raises(DataError, match="rotor speeds"):
        speed_scale(flight.without("rpm1"))


@pytest.mark.slow
def test_the_test_flights_never_reach_the_choice(monkeypatch):
    """Through identify (in process): select_rotation sees the training flights' stretches only;
    the test flights are scored after the choice, with the final v̇ models."""
    import droneid.rotation.stage as stage
    from droneid.identify.pipeline import IdentifyConfig, identify
    from droneid.rotation.choice import RotationChoice
    from droneid.simulation.simulator import simulate
    seen = []

    def fake_select(logs, layout, **kw):
        seen.extend(log.name for log in logs)
        held = {"rates_simerr": 3.0, "attitude_simerr": 1.0, "rates_axis_simerr": [1.0, 1.0, 1.0]}
        ladder = tuple({"axis": ax, "choice": "held", "alpha": 0.01, "family_size": 6, "regimes": 4,
                        "flights": ["train1", "train2"], "steps": []} for ax in ("roll", "pitch", "yaw"))
        return RotationChoice(None, (), held, None, ("held",) * 3, ladder)

    monkeypatch.setattr(stage, "select_rotation", fake_select)
    train = [_named(simulate(path="circle", duration_s=6, seed=s).flight, f"train{s}") for s in (1, 2)]
    test = [_named(simulate(path="circle", duration_s=6, seed=3).flight, "test3")]
    cfg = IdentifyConfig.make(runs=1, generations=50, population_size=60, jobs=1, frame="quad_x")
    rot = identify(train, test, cfg).rotation
    assert seen and set(seen) == {"train1", "train2"}
    assert rot.model is None and [a.verdict_kind for a in rot.axes] == ["no better"] * 3
    assert rot.layout == "quad_x" and rot.layout_source == "--frame"
    assert all(math.isfinite(a.test_held) for a in rot.axes)     # scored, after the choice


def _named(flight, name):
    from dataclasses import replace
    return replace(flight, provenance=replace(flight.provenance, files=(f"{name}.csv",)))


def test_one_training_flight_cannot_choose():
    from droneid.simulation.simulator import simulate
    with pytest.raises(DataError, match="at least two training flights"):
        choose_rotation([simulate(path="circle", duration_s=6, seed=1).flight], frame="quad_x")


def test_the_record_reads_back():
    axes = tuple(AxisResult(t, "damping", 60.0, 20.0, math.nan, math.nan, "text", "better")
                 for t in ("wx_dot", "wy_dot", "wz_dot"))
    rot = RotationResult("crazyflie_x", "--frame", 0.0175, "erpm", None, {"held": {}}, axes,
                         {"constant": {"1": {"position": 0.1}}}, ("a note",))
    back = RotationResult.from_dict(rot.to_dict())
    assert back.to_dict() == rot.to_dict()
    assert math.isnan(back.axes[0].test_held)
    with pytest.raises(DataError, match="rotation section is damaged"):
        RotationResult.from_dict({"layout": "x"})


def test_the_report_section_draws_the_drift_without_a_warning():
    import warnings
    from droneid.report.document import Document
    from droneid.report.rotation import rotation_lines, rotation_section
    per = {str(h): {"position": 0.01 * h, "velocity": 0.02 * h, "attitude": 0.005 * h, "rates": 0.1}
           for h in range(1, 51)}
    per["simerr"] = {"position": 12.75, "velocity": 25.5, "attitude": 6.4, "rates": 5.0}
    axes = tuple(AxisResult(t, "held", 5.0, 5.0, 6.0, 6.0, f"{t}: held", "no better") for t in ("wx_dot", "wy_dot", "wz_dot"))
    rot = RotationResult("quad_x", "--frame", 0.1047, "rpm", None, {}, axes, {"identified": per, "constant": per})
    doc = Document("t")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rotation_section(doc, rot)
        files = doc.files("report")
    assert "open_loop_drift.png" in files and "ω̇x = 0 (rate held)" in files["report.md"]
    text = "\n".join(rotation_lines(rot))
    assert "50 steps" in text and "SimErr" in text and "wz_dot: held" in text


def test_the_report_gives_a_taken_spinup_rung_its_settings_and_interval():
    from droneid.report.rotation import rotation_lines
    from droneid.rotation.choice import per_axis_model
    from droneid.rotation.spinup import Spinup
    from priors.torque import get_layout
    spin = Spinup(3, 0.03, 0.05, 1.0)
    model = per_axis_model(("damping", "damping", "spinup"), [4.0, 2.0, 1.0], None, get_layout("crazyflie_x"),
                           0.0175, spinup=spin)
    axes = tuple(AxisResult(t, r, 5.0, 4.0, 6.0, 5.0, f"{t}: {r}", "better")
                 for t, r in zip(("wx_dot", "wy_dot", "wz_dot"), ("damping", "damping", "spinup")))
    choice = {"table": [{"method": "spinup", **spin.to_dict(), "gain_interval": [0.02, 0.1]}]}
    text = "\n".join(rotation_lines(RotationResult("crazyflie_x", "--frame", 0.0175, "erpm", model, choice, axes)))
    assert "ω̇z = +1·(−ω) +0.05·(P ṡpin) (spinup)" in text
    assert "3 step(s) earlier, motor lag 30 ms; spin-up gain 95 % bootstrap interval 0.02-0.1" in text
    assert "NOT STEERABLE on roll, pitch:" in text     # yaw answers the motors through its spin-up
