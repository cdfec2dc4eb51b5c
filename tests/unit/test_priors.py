import math

import numpy as np
import pytest
import sympy as sp

from droneid.dataset.builder import DatasetBuilder
from droneid.errors import ConfigError, DataError, MissingSignalError
from droneid.core.expressions import symbol
from priors.registry import PRIORS, PriorFeature, get_prior, load_priors, resolve_prior

from synth_flights import tilt_drag_flight


def test_registry_reachable_by_name_and_typos_suggest():
    for name in PRIORS:
        p = get_prior(name)
        for target in p.targets:
            assert p.features(target)
            assert p.inputs(target)
    with pytest.raises(ConfigError, match="did you mean 'tilt-drag'"):
        get_prior("tilt_drag")
    with pytest.raises(ConfigError, match="did you mean 'k_D'"):
        get_prior("tilt-drag", kD=0.3)
    with pytest.raises(ConfigError, match="finite number"):
        get_prior("tilt-drag", g=float("nan"))


def test_tilt_drag_terms_are_the_papers():
    p = get_prior("tilt-drag")
    vx, phi, th, psi = (symbol(n) for n in ("vx", "roll", "pitch", "yaw"))
    three = p.features("vx_dot", 3)
    assert [type(f) for f in three] == [PriorFeature] * 3
    assert sp.simplify(three[0].expr - 9.81 * sp.cos(psi) * sp.tan(th) / sp.cos(phi)) == 0
    assert sp.simplify(three[1].expr - 9.81 * sp.sin(psi) * sp.tan(phi)) == 0
    assert sp.simplify(three[2].expr + 0.28 * vx) == 0
    one = p.features("vx_dot", 1)
    assert len(one) == 1 and sp.simplify(one[0].expr - sum(f.expr for f in three)) == 0
    vy = symbol("vy")
    y3 = p.features("vy_dot")
    assert sp.simplify(sum(f.expr for f in y3) - (9.81 * sp.sin(psi) * sp.tan(th) / sp.cos(phi)
                                                  - 9.81 * sp.cos(psi) * sp.tan(phi) - 0.28 * vy)) == 0
    assert p.inputs("vx_dot") == ("vx", "pitch", "roll", "yaw")
    assert p.inputs("vy_dot") == ("vy", "pitch", "roll", "yaw")
    assert get_prior("tilt-drag", g=9.7, k_D=0.5).params == {"g": 9.7, "k_D": 0.5}
    with pytest.raises(ConfigError, match="must be 1 or 3"):
        p.features("vx_dot", 2)
    with pytest.raises(ConfigError, match="no model of 'vz_dot'"):
        p.features("vz_dot")


def test_unicycle():
    p = get_prior("unicycle")
    assert p.inputs("x_dot") == ("x", "y", "yaw", "v_f", "v_a")
    cols = {"v_f": np.array([0.2, 0.2]), "yaw": np.array([0.0, math.pi / 2])}
    np.testing.assert_allclose(p.evaluate(cols, "x_dot")[:, 0], [0.2, 0.0], atol=1e-15)
    np.testing.assert_allclose(p.evaluate(cols, "y_dot")[:, 0], [0.0, 0.2], atol=1e-15)


def test_evaluate_errors_name_the_prior_and_signal():
    p = get_prior("tilt-drag")
    cols = {"vx": np.zeros(3), "pitch": np.zeros(3), "roll": np.zeros(3)}
    with pytest.raises(MissingSignalError, match="'yaw'.*prior 'tilt-drag'"):
        p.evaluate(cols, "vx_dot")
    cols["yaw"] = np.zeros(3)
    cols["pitch"] = np.array([0.1, math.pi / 2, -math.pi / 2])
    cols["t"] = np.array([1.0, 2.0, 3.0])
    # tan(±pi/2) is ~1e16 in floating point: beyond 1e12 counts as non-finite
    with pytest.raises(DataError, match=r"prior 'tilt-drag'.*on 2 of 3 samples.*t = 2\.000 s \.\. 3\.000 s"):
        p.evaluate(cols, "vx_dot")
    cols["pitch"] = np.array([0.1, 0.0, 0.0])
    cols["roll"] = np.array([0.0, 0.0, np.nan])
    with pytest.raises(DataError, match=r"on 1 of 3 samples"):
        p.evaluate(cols, "vx_dot")


def test_ls_on_three_tilt_drag_features_recovers_the_planted_model():
    k_true = 0.35
    f = tilt_drag_flight(duration_s=30.0, k_D=k_true)
    p = get_prior("tilt-drag")
    for method, tol in (("central", 0.01), ("forward", 0.05)):
        ds = DatasetBuilder(method=method).build(f, "vx_dot")
        F = p.evaluate(ds.columns(), "vx_dot", 3)
        A = np.column_stack([F, np.ones(len(ds))])
        beta = np.linalg.lstsq(A, ds.y, rcond=None)[0]
        assert beta[0] == pytest.approx(1.0, abs=tol)             # g-scale on the pitch term
        assert beta[1] == pytest.approx(1.0, abs=tol)             # g-scale on the roll term
        assert beta[2] * 0.28 == pytest.approx(k_true, abs=tol)   # k_D
        assert abs(beta[3]) < tol


TOML = '''
[prior.mydrag]
description = "tilt plus quadratic drag"
target = "vx_dot"
features = ["g*cos(yaw)*tan(pitch)/cos(roll)", "-k_D*vx*abs(vx)"]
names = ["tilt", "quadratic_drag"]
[prior.mydrag.params]
g = 9.81
k_D = 0.3

[prior.both.features]
vx_dot = ["g*cos(yaw)*tan(pitch)/cos(roll) + g*sin(yaw)*tan(roll)", "-vx"]
vy_dot = ["g*sin(yaw)*tan(pitch)/cos(roll) - g*cos(yaw)*tan(roll)", "-vy"]
[prior.both.params]
g = 9.81

[prior.robot]
target = "x_dot"
signals = ["v_f"]
features = ["v_f*cos(yaw)"]
inputs = ["x", "y", "yaw", "v_f"]
'''


def test_user_priors_from_toml(tmp_path):
    path = tmp_path / "priors.toml"
    path.write_text(TOML)
    models = load_priors(path)
    assert set(models) == {"mydrag", "both", "robot"}
    md = models["mydrag"]
    assert [f.name for f in md.features("vx_dot")] == ["tilt", "quadratic_drag"]
    cols = {"vx": np.array([2.0]), "pitch": np.array([0.0]), "roll": np.array([0.0]), "yaw": np.array([0.0])}
    np.testing.assert_allclose(md.evaluate(cols, "vx_dot"), [[0.0, -1.2]])
    assert md.inputs("vx_dot") == ("pitch", "roll", "vx", "yaw")
    assert set(models["both"].targets) == {"vx_dot", "vy_dot"}
    assert len(models["both"].features("vy_dot", 1)) == 1
    assert models["robot"].inputs("x_dot") == ("x", "y", "yaw", "v_f")
    assert resolve_prior(f"{path}:robot") is not None
    assert resolve_prior("tilt-drag").name == "tilt-drag"


@pytest.mark.parametrize("body, match", [
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["__import__(\'os\').system(\'true\')"]', "not allowed"),
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["vx.__class__"]', "not allowed"),
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["open(vx)"]', "function 'open' is not allowed"),
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["vxx*2"]', "unknown name 'vxx'"),
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["2*g"]\n[prior.evil.params]\ng = 9.81', "uses no signal"),
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["vx"]\n[prior.evil.params]\nsin = 1.0', "parameter name 'sin'"),
    ('[prior.evil]\nfeatures = ["vx"]', "needs target"),
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["vx"]\ncode = "x"', "unknown key 'code'"),
    ('[prior.evil]\ntarget = "vx_dot"\nfeatures = ["vx"]\nnames = ["a b"]', "not an identifier"),
    ('[prior.evil\ntarget = 1', "not valid TOML"),
])
def test_bad_user_priors_name_file_and_prior(tmp_path, body, match):
    path = tmp_path / "bad.toml"
    path.write_text(body)
    with pytest.raises(ConfigError, match=match) as exc:
        load_priors(path)
    assert "bad.toml" in str(exc.value)
    if "not valid TOML" not in match:
        assert "prior 'evil'" in str(exc.value)


def test_shipped_example_files_load():
    from pathlib import Path

    from priors.constraints import load_constraints
    root = Path(__file__).resolve().parents[2] / "priors"
    models = load_priors(root / "example_priors.toml")
    assert set(models) == {"tilt-quadratic-drag", "hover-thrust"}
    assert len(models["tilt-quadratic-drag"].features("vy_dot")) == 3
    cs = load_constraints(root / "example_constraints.toml")
    assert len(cs) == 3 and cs.target == "vx_dot"
    s = cs.sample(("vx", "pitch", "roll", "yaw", "throttle"), 10, seed=0)
    cols = {n: s.X[:, i] for i, n in enumerate(s.input_names)}
    from droneid.core.constraint_samples import constraint_rmse
    pred = get_prior("tilt-drag").evaluate(cols, "vx_dot", 1)[:, 0]
    assert constraint_rmse(pred, s) < 1e-12  # the paper's model meets these too


def test_a_user_prior_declares_its_vehicle_and_its_constraint_file(tmp_path):
    (tmp_path / "c.toml").write_text('target = "vx_dot"\n[[constraint]]\n'
                                     'domain = { vx = 0, pitch = 0, roll = 0, yaw = ["-pi", "pi"] }\n')
    (tmp_path / "p.toml").write_text('[prior.t]\nvehicle = "multirotor"\nconstraints = "c.toml"\n'
                                     'target = "vx_dot"\nfeatures = ["9.81*tan(pitch)", "-0.3*vx"]\n')
    p = load_priors(tmp_path / "p.toml")["t"]
    assert p.vehicle == "multirotor" and p.constraints == str(tmp_path / "c.toml")   # relative to the file
    from droneid.identify.pipeline import IdentifyConfig
    from droneid.identify.problem import constraint_sets as _constraint_set_for
    train_cs, eval_cs = _constraint_set_for(IdentifyConfig.make(effects="none", delays="none"), "vx_dot", p)
    assert train_cs is not None and len(train_cs.constraints) == 1
    for bad, msg in (('vehicle = "boat"', "vehicle must be one of"), ('constraints = "nope.toml"', "not found"),
                     ('constraints = "paper"', "must name a constraints TOML")):
        (tmp_path / "b.toml").write_text(f'[prior.t]\n{bad}\ntarget = "vx_dot"\nfeatures = ["-0.3*vx"]\n')
        with pytest.raises(ConfigError, match=msg):
            load_priors(tmp_path / "b.toml")


def test_a_new_module_in_the_prior_catalogue_is_a_built_in_prior(tmp_path, monkeypatch):
    """Adding a built-in prior is one module: NAME, ORDER, FACTORY (docs/extending.md)."""
    import sys

    import priors.prior_catalogue as package
    from priors import registry as models
    (tmp_path / "hover_only.py").write_text(
        "from droneid.core.expressions import symbol\n"
        "from priors.base import PriorFeature, PriorModel\n"
        "NAME, ORDER = 'hover-only', 40\n"
        "def FACTORY():\n"
        "    return PriorModel('hover-only', 'drag only', {'vx_dot': (PriorFeature('d', -0.3 * symbol('vx')),)})\n")
    monkeypatch.setattr(package, "__path__", [*package.__path__, str(tmp_path)])
    try:
        found = models._discover()
    finally:
        sys.modules.pop("priors.prior_catalogue.hover_only", None)
    assert list(found) == [*PRIORS, "hover-only"] and found["hover-only"]().targets == ("vx_dot",)
