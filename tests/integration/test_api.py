"""The Python API in the field's conventions (issue 39.4): Identifier stores its parameters
verbatim (get_params / set_params), predict returns predictions, score the typed error tables,
and every repr is a summary. One tiny identification (about 2 s) on a sample log serves all."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

import droneid
from droneid.errors import ConfigError
from droneid.use.score import Score

ROOT = Path(__file__).resolve().parents[2]
TINY = dict(quick=True, runs=1, generations=200, population_size=50, effects="none", delays="none",
            rotation="none", targets="vx_dot,vz_dot", jobs=1)


@pytest.fixture(scope="module")
def result():
    flight = droneid.read_log(ROOT / "sample_logs" / "rotor_climb_eight.flat.csv")
    return droneid.Identifier(prior="rotor-thrust", **TINY).fit([flight])


@pytest.fixture(scope="module")
def other():
    return droneid.read_log(ROOT / "sample_logs" / "wind_quadratic_eight.flat.csv")


def test_the_identifier_keeps_its_parameters_as_given():
    ident = droneid.Identifier(prior="rotor-thrust", constraints="prior", runs=2, targets="vx_dot")
    params = ident.get_params()
    assert params["prior"] == "rotor-thrust" and params["constraints"] == "prior"
    assert params["runs"] == 2 and params["targets"] == "vx_dot"          # verbatim, not parsed
    assert droneid.Identifier(**params).get_params() == params             # scikit-learn's clone
    assert ident.set_params(runs=3, effects="none") is ident
    assert ident.get_params()["runs"] == 3 and ident.effects == "none"
    assert repr(ident) == "Identifier(prior='rotor-thrust', effects='none', runs=3, targets='vx_dot')"


def test_a_misspelt_parameter_is_named_with_the_nearest():
    with pytest.raises(ConfigError, match="did you mean 'seed'"):
        droneid.Identifier().set_params(sed=1)
    with pytest.raises(ConfigError, match="did you mean 'runs'"):
        droneid.Identifier(runz=2).config
    with pytest.raises(ConfigError, match="'differentiator'"):
        droneid.Identifier(differentiator="centre").config


def test_prior_names_the_prior_s_own_constraints_and_paper_stays_an_alias():
    assert droneid.Identifier(constraints="prior").config == droneid.Identifier(constraints="paper").config
    assert droneid.Identifier(constraints="none").config.constraints == "none"


def test_predict_returns_vdot_on_the_flight_s_grid(result, other):
    pred = result.predict(other)
    assert set(pred.targets) == {"vx_dot", "vz_dot"} and pred.sources == (other.name,)
    vx = pred.targets["vx_dot"]
    assert vx.unit == "m/s^2" and vx.t_s.shape == vx.final.shape == vx.measured.shape == vx.refit.shape
    steps = np.diff(vx.t_s)
    assert np.allclose(steps[steps < 1.5 * pred.ts], pred.ts)               # a grid at the identified period
    assert other.start_s <= vx.t_s.min() and vx.t_s.max() <= other.end_s
    frame = pred.to_frame("vx_dot")
    assert list(frame.columns) == ["flight", "t_s", "measured", "final", "empirical", "refit"]
    np.testing.assert_array_equal(frame["final"].to_numpy(), vx.final)
    both = pred.to_frame()
    assert list(both.columns[:2]) == ["target", "flight"] and len(both) == sum(t.t_s.size for t in pred.targets.values())
    # the final model evaluated by hand on the log at those times (no delays in this tiny run)
    model = result.targets["vx_dot"].final
    cols = {s: np.interp(vx.t_s, other[s].t, other[s].values) for s in model.signals}
    np.testing.assert_allclose(vx.final, model.evaluate(cols), rtol=1e-6, atol=1e-9)


def test_the_score_is_the_rmse_of_the_prediction(result, other):
    pred, score = result.predict([other]), result.score(other)
    assert isinstance(score, Score)
    for t, p in pred.targets.items():
        e = score.targets[t].errors["all"]
        assert e.n == p.t_s.size
        assert math.isclose(e.rmse_identified, float(np.sqrt(np.mean((p.final - p.measured) ** 2))), rel_tol=1e-12)
        assert math.isclose(e.rmse_refit, float(np.sqrt(np.mean((p.refit - p.measured) ** 2))), rel_tol=1e-12)
    back = Score.from_dict(json.loads(json.dumps(score.to_dict())))
    assert back == score


def test_horizons_give_the_simulated_states_and_their_errors(result, other):
    pred = result.predict(other, horizons=(1, 5))
    score = result.score(other, horizons=(1, 5))
    assert pred.horizons == (1, 5) and pred.dt_s > 0
    states = pred.states_frame(5)
    np.testing.assert_allclose(states["t_s"] - states["t0_s"], 5 * pred.dt_s)
    for axis in ("vx", "vz"):
        rms = float(np.sqrt(np.mean((states[axis] - states[f"{axis}_logged"]) ** 2)))
        assert math.isclose(rms, getattr(score.horizons["identified"][5], axis), rel_tol=1e-9)
    with pytest.raises(ConfigError):
        pred.states_frame(7)


def test_every_repr_is_a_short_summary(result, other):
    for obj in (result, result.targets["vx_dot"], result.predict(other), result.score(other),
                result.predict(other).targets["vx_dot"]):
        text = repr(obj)
        assert len(text) < 1000 and len(text.splitlines()) <= 5, text


def test_the_package_exports_the_typed_results():
    from droneid.use.prediction import PredictionResult
    assert droneid.PredictionResult is PredictionResult and droneid.Score is Score
    assert {"PredictionResult", "Score"} <= set(droneid.__all__)
