"""``droneid export`` on a real Crazyflie log (moved from tests/integration/test_export.py): the
exported Python and the compiled C compute what ``predict`` computes."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.closed_form import IdentifiedModel

from conftest import real_log
from export_helpers import CC, c_eval, c_library, export_cli, python_module, rotor_thrust_sum, write_result

pytestmark = pytest.mark.real_logs


def test_exported_code_matches_predict_on_a_real_crazyflie_log(tmp_path):
    """The rotor-thrust prior summed, on the Crazyflie square_run2 log at its 100 Hz: the values
    ``predict`` computes (IdentifiedModel.evaluate on the dataset it builds), the exported Python
    and the compiled C agree to 1e-9 relative."""
    from droneid.dataset_builder import DatasetBuilder
    from droneid.predict import _predict_final
    from parsers import read_flight
    flight = read_flight(real_log("mocap/crazyflie_nanodrone/square_run2.csv"))
    m = IdentifiedModel("vx_dot", rotor_thrust_sum("vx_dot").expr, description="rotor-thrust prior, summed")
    ds, preds, _ = _predict_final(DatasetBuilder(ts=0.01, method="forward"), [flight], "vx_dot", {"identified": m})
    cols = ds.columns()
    want = preds["identified"]
    assert len(ds) > 1500 and np.isfinite(want).all() and np.std(want) > 0.1
    result = write_result(tmp_path, [m])
    py = python_module(export_cli(tmp_path, result, "python", "cf.py"))
    np.testing.assert_allclose(py.vx_dot(**{s: cols[s] for s in m.signals}), want, rtol=1e-9, atol=0)
    if CC is None:
        pytest.skip("no C compiler (gcc / cc) on this machine")
    lib = c_library(tmp_path, export_cli(tmp_path, result, "c", "cf.c"))
    np.testing.assert_allclose(c_eval(lib, m, cols), want, rtol=1e-9, atol=0)
