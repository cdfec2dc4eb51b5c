"""Command-driven vehicles on real logs (issue 36): ArduCopter log171 and 4.6.2, PX4 SITL x500.

No thrust term is held at a nominal value for collinearity (the command map is one curve with a
shape chosen from the data, not two collinear terms), every verdict says what it can about the
curve, and where the log's PARM declares MOT_THST_EXPO / MOT_THST_HOVER the identified value
stands beside the declared one. The physical ladder is built as identify builds it (no SNGP)."""
import pytest

from conftest import real_log

pytestmark = [pytest.mark.real_logs, pytest.mark.slow]

LOGS = ("ardupilot/copter33_quad_log171.bin", "px4/x500_sitl_events.ulg")


def _ladders(path):
    from droneid.identify.pipeline import IdentifyConfig, prepare_target, summarise_target
    from droneid.diagnosis.diagnose import plan_identification
    from parsers import read_flight
    train = [read_flight(str(real_log(path)))]
    cfg = IdentifyConfig.make(quick=True)
    plan = plan_identification(train, cfg)
    return plan, {t: summarise_target(prepare_target(train, None, t, cfg, plan), cfg, []) for t in plan.targets}


@pytest.fixture(scope="module", params=LOGS)
def identified(request):
    return request.param, *_ladders(request.param)


def test_no_thrust_term_is_held_and_the_verdict_names_the_curve(identified):
    path, plan, targets = identified
    curve = plan.thrust_curve
    assert curve is not None and plan.prior.params["source"] == "motor"
    lo, hi = curve.interval
    assert 0.0 <= lo <= curve.expo <= hi <= 1.0
    for t, tr in targets.items():
        thrust = [k for k in tr.final_rung.terms if "cmd_curve" in k]
        assert len(thrust) == 1, (path, t, tr.final_rung.terms)      # one term, not a collinear pair
        assert not any("cmd" in k for k in tr.final_rung.held), (path, t, tr.final_rung.held)
        assert "thrust curve" in tr.verdict, tr.verdict


def test_declared_expo_and_hover_are_shown_beside_the_identified(identified):
    path, plan, _ = identified
    curve = plan.thrust_curve
    d = curve.to_dict()
    text = curve.text()
    if "copter33" in path:        # log171 (ArduCopter 3.3) declares the older names
        assert d["declared"] == {"MOT_THST_EXPO": 0.8, "MOT_THST_BAT_MAX": 16.8, "MOT_THST_BAT_MIN": 12.0,
                                 "THR_MID": 400.0}
        assert "MOT_THST_EXPO 0.8 (identified" in text and "MOT_THST_EXPO 0.8" in curve.verdict()
        # 3.3's name of MOT_BAT_VOLT_MAX is the compensation's V_ref; its hover throttle is shown
        assert "u·V/16.8 V (the log's MOT_THST_BAT_MAX)" in text
        assert "THR_MID 400 (the hover throttle of ArduCopter before 3.5: 0.4 of full; identified" in text
    else:                         # a PX4 log declares none of these
        assert d["declared"] == {} and "declares" not in text


def test_arducopter_462_declares_its_curve_normalisation_and_voltage_scaling():
    """The 4.6.2 log (too little flight to identify) declares the whole command map in PARM: the
    reader keeps it, and the command prior runs its curve from MOT_SPIN_MIN to MOT_SPIN_MAX."""
    from droneid.fitting.thrust_curve import declared_parameters, normalised
    from parsers import read_flight
    from priors.registry import get_prior
    f = read_flight(str(real_log("ardupilot/copter462_quad_first80k.bin")))
    d = declared_parameters([f])
    assert d["MOT_THST_EXPO"] == 0.6 and d["MOT_THST_HOVER"] == pytest.approx(0.3122511)
    assert d["MOT_SPIN_MIN"] == 0.08 and d["MOT_SPIN_MAX"] == 0.95 and d["MOT_BAT_VOLT_MAX"] == 16.8
    p = normalised(get_prior("rotor-thrust", source="motor"), [f])
    assert (p.params["spin_min"], p.params["spin_max"]) == (0.08, 0.95)
    import numpy as np
    cols = {n: np.array([0.08, 0.95]) for n in p.inputs("vz_dot")}
    cols.update(roll=np.zeros(2), pitch=np.zeros(2), yaw=np.zeros(2), vz=np.zeros(2))
    thrust = p.evaluate(cols, "vz_dot")[:, 0]     # no thrust at spin min, full thrust at spin max
    assert thrust[0] == pytest.approx(0.0, abs=1e-12) and thrust[1] == pytest.approx(4 * p.params["k_T"])
