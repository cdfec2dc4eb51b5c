"""Start-up of the engine in a fresh process (issue 26): what `droneid fit` imports, and that
reading the cached kernels without numba's target set-up (kernels.load_from_cache_lightly)
leaves the results bit for bit the same."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

_FIT = """
import json, sys
import numpy as np
from droneid.sngp import SNGPRegressor, kernels
if sys.argv[1] == "numba":
    kernels.load_from_cache_lightly(on=False)    # numba's own loading, full target set-up
rng = np.random.default_rng(3)
X = rng.uniform(-1, 1, (120, 3))
y = np.sin(X[:, 0]) * X[:, 1] + 0.3 * X[:, 2] ** 2 + 0.01 * rng.normal(size=120)
m = SNGPRegressor(generations=3000, population_size=100, seed=5, simplify_s=0).fit(X, y)
print(json.dumps({"model": m.model_.to_dict(), "rmse": m.rmse_train_.hex(),
                  "light": "load_overload" in vars(kernels.run_chunk._cache),
                  "full_set_up": "numba.np.arraymath" in sys.modules,
                  "scipy_linalg": "scipy.linalg" in sys.modules}))
"""


def _fit(mode: str) -> dict:
    r = subprocess.run([sys.executable, "-c", _FIT, mode], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr == "", r.stderr     # no warning from either way of loading
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_light_kernel_loading_skips_numbas_set_up_and_keeps_the_model_bit_for_bit():
    numba_own, light = _fit("numba"), _fit("light")
    assert light["model"] == numba_own["model"] and light["rmse"] == numba_own["rmse"]
    assert numba_own["full_set_up"] and numba_own["scipy_linalg"]
    assert not light["full_set_up"] and not light["scipy_linalg"]
    assert light["light"] and not numba_own["light"]   # a fit did not undo the process's choice


def test_importing_the_engine_changes_nothing_in_numba():
    # the light loading is applied by a fit's first kernel call, not by an import (STYLE.md)
    code = ("import json, droneid.sngp, droneid.sngp.precompile as p; from droneid.sngp import kernels as K; "
            "print(json.dumps([name for name in K.ENTRY_KERNELS "
            "if 'load_overload' in vars(getattr(K, name)._cache)]))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == []


@pytest.mark.slow   # compiles every kernel once (~30 s)
def test_light_loading_falls_back_to_numba_when_the_cache_has_no_entry(tmp_path):
    # an empty cache folder: every kernel is compiled by numba, with its full set-up, then read
    # back lightly by a second process; three processes, one model
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    outs = []
    for _ in range(2):
        r = subprocess.run([sys.executable, "-c", _FIT, "light"], capture_output=True, text=True,
                           timeout=600, env=env)
        assert r.returncode == 0, r.stderr
        outs.append(json.loads(r.stdout.strip().splitlines()[-1]))
    compiled, loaded = outs
    assert compiled["full_set_up"] and not loaded["full_set_up"]
    assert compiled["model"] == loaded["model"] == _fit("light")["model"]


_PROBE = """
import json, sys
from droneid.cli import main
rc = main(sys.argv[1:])
print(json.dumps({"rc": rc, "modules": sorted(sys.modules)}))
"""


def test_droneid_fit_imports_neither_pandas_nor_scipy_on_a_plain_table(tmp_path):
    import numpy as np
    table = tmp_path / "t.csv"
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (80, 2))
    np.savetxt(table, np.c_[x, x[:, 0] - x[:, 1] ** 2], delimiter=",", header="a,b,y", comments="")
    r = subprocess.run([sys.executable, "-c", _PROBE, "fit", str(table), "--target", "y",
                        "--generations", "300", "--population", "60", "-q"],
                       capture_output=True, text=True, timeout=300)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["rc"] == 0, r.stderr
    loaded = set(out["modules"])
    assert "pandas" not in loaded and "scipy.linalg" not in loaded
    assert "numba.np.arraymath" not in loaded    # numba's compiler set-up was not needed
    assert "sympy" in loaded   # the equation is printed: sympy comes, in the background
