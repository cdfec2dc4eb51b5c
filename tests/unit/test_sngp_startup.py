"""Start-up of the engine in a fresh process (issue 26): what `droneid fit` imports, and that
setting numba up without its BLAS probe leaves the results bit for bit the same."""
from __future__ import annotations

import json
import subprocess
import sys

_FIT = """
import json, sys
import numpy as np
from droneid.sngp import SNGPRegressor, kernels
if sys.argv[1] == "skip":
    kernels.set_up_target(skip_blas_probe=True)
rng = np.random.default_rng(3)
X = rng.uniform(-1, 1, (120, 3))
y = np.sin(X[:, 0]) * X[:, 1] + 0.3 * X[:, 2] ** 2 + 0.01 * rng.normal(size=120)
m = SNGPRegressor(generations=3000, population_size=100, seed=5, simplify_s=0).fit(X, y)
scipy_linalg = "scipy.linalg" in sys.modules
import scipy.linalg.cython_blas   # still importable afterwards
print(json.dumps({"model": m.model_.to_dict(), "rmse": m.rmse_train_.hex(),
                  "scipy_linalg": scipy_linalg}))
"""


def _fit(mode: str) -> dict:
    r = subprocess.run([sys.executable, "-c", _FIT, mode], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_skipping_numbas_blas_probe_keeps_scipy_out_and_the_model_bit_for_bit():
    plain, skipped = _fit("plain"), _fit("skip")
    assert skipped["model"] == plain["model"] and skipped["rmse"] == plain["rmse"]
    assert plain["scipy_linalg"] and not skipped["scipy_linalg"]


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
    assert "sympy" in loaded   # the equation is printed: sympy comes, in the background
