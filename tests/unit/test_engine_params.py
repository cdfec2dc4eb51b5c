"""One set of engine parameter names: the configs speak the estimator's own names, so a setting
reaches SNGPRegressor under the name its signature gives (no translation table to drift)."""
import inspect

from droneid.diagnosis.diagnose import DiagnoseConfig
from droneid.identify.pipeline import IdentifyConfig
from droneid.sngp import SNGPRegressor

ENGINE = set(SNGPRegressor.param_names())


def test_param_names_are_the_signature():
    sig = inspect.signature(SNGPRegressor.__init__).parameters
    assert set(SNGPRegressor.param_names()) == {n for n, p in sig.items() if p.kind is p.KEYWORD_ONLY}


def test_identify_engine_params_use_the_estimator_names():
    cfg = IdentifyConfig.make(generations=123, population_size=45, prune="exact")
    params = cfg.engine_params()
    assert set(params) == {"generations", "population_size", "n_features", "max_depth", "gamma",
                           "simplify_s", "prune"}
    assert params["generations"] == 123 and params["population_size"] == 45 and params["prune"] == "exact"
    SNGPRegressor(**params)                      # accepted as is: no unknown parameter


def test_diagnose_search_settings_use_the_estimator_names():
    names = {f for f in DiagnoseConfig.__dataclass_fields__}
    for old in ("sngp_generations", "sngp_population", "ts_s"):
        assert old not in names
    assert {"generations", "population_size", "n_features", "max_depth", "seed"} <= names & ENGINE
