"""``droneid export`` on a real Crazyflie log (moved from tests/integration/test_export.py): the
exported Python and the compiled C compute what ``predict`` computes."""
from __future__ import annotations

import numpy as np
import pytest

from droneid.fitting.closed_form import IdentifiedModel

from conftest import real_log
from export_helpers import CC, c_eval, c_library, export_cli, python_module, rotor_thrust_sum, write_result

pytestmark = pytest.mark.real_logs


def test_exported_code_matches_predict_on_a_real_crazyflie_log(tmp_path):
    """The rotor-thrust prior summed, on the Crazyflie square_run2 log at its 100 Hz: the values
    ``predict`` computes (IdentifiedModel.evaluate on the dataset it builds), the exported Python
    and the compiled C agree to 1e-9 relative."""
    from droneid.dataset.builder import DatasetBuilder
    from droneid.use.predict import _predict_final
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


def test_vehicle_export_steps_as_the_open_loop_simulation_on_a_real_crazyflie_flight(tmp_path):
    """``export --vehicle`` of a result holding the rotor-thrust prior's v̇ models (rpm1 read 20 ms
    late) and a rotational model fitted on square_run1 with every term, a one-step delay, a
    low-pass and the running balance: fed the logged motor speeds of melon_run1 from its start,
    the exported Python and the compiled C step 50 steps from the logged state at three in-flight
    starts as droneid's open-loop simulation does (IdentifiedVehicle(IdentifiedTranslation, rotation),
    what predict --open-loop scores), to 1e-9."""
    import json

    from droneid.simulation.openloop import IdentifiedTranslation, IdentifiedVehicle, simulate, state_log
    from droneid.rotation.model import KNOWN_TERMS, fit_rotation, flying_mask
    from export_helpers import vehicle_c_rollout, vehicle_python_rollout
    from parsers import read_flight
    train = state_log(read_flight(real_log("mocap/crazyflie_nanodrone/square_run1.csv")))
    log = state_log(read_flight(real_log("mocap/crazyflie_nanodrone/melon_run1.csv")))
    rotation = fit_rotation([train], "crazyflie_x", terms=KNOWN_TERMS, delay_steps=1, lowpass_tau_s=0.03,
                            balance_weight_s=2.0)
    models = {t: rotor_thrust_sum(t) for t in ("vx_dot", "vy_dot", "vz_dot")}
    path = write_result(tmp_path, list(models.values()))
    doc = json.loads(open(path).read())
    doc.update(rotation={"model": rotation.to_dict(), "dt_s": log.dt_s})
    open(path, "w").write(json.dumps(doc))
    from droneid.cli import main
    assert main(["export", path, "--vehicle", "--to", "python", "-o", str(tmp_path / "v.py")]) == 0
    assert main(["export", path, "--vehicle", "--to", "c", "-o", str(tmp_path / "v.c")]) == 0
    veh = IdentifiedVehicle(IdentifiedTranslation(models), rotation)
    u = veh.inputs(log)
    flying = np.flatnonzero(flying_mask(log))
    for start in (int(flying[len(flying) // 4]), int(flying[len(flying) // 2]), int(flying[3 * len(flying) // 4])):
        ref = simulate(veh, log.state[start][None], u[None, start:start + 50], log.dt_s)[0]
        assert np.ptp(ref[:, 10:13], axis=0).max() > 0.05 and np.isfinite(ref).all()   # the rates move
        py = vehicle_python_rollout(open(tmp_path / "v.py").read(), log.rpm, log.state[start], start, 50, u)
        np.testing.assert_allclose(py, ref, rtol=1e-9, atol=1e-9, err_msg=f"python, start {start}")
        if CC is not None:
            c = vehicle_c_rollout(tmp_path, open(tmp_path / "v.c").read(), log.rpm, log.state[start], start, 50)
            np.testing.assert_allclose(c, ref, rtol=1e-9, atol=1e-9, err_msg=f"C, start {start}")
    if CC is None:
        pytest.skip("no C compiler (gcc / cc) on this machine: the Python agreed, the C was not built")
