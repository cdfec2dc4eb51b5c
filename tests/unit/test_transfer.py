"""predict's check of a result's vehicle constants on other flights (droneid.use.transfer): a flight
of the same vehicle keeps them, one whose thrust per unit mass differs (another vehicle, a
payload) is flagged, a constant held or bounded in the result is no estimate and is not checked,
and a result written before term roles were recorded has nothing to check."""
from __future__ import annotations

import numpy as np

from droneid.use.transfer import ConstantCheck, check_constants, constants_line, identified_constants

TR = {"empirical_terms": [{"name": "thrust_z", "expr": "2.0*u", "role": "thrust"},
                          {"name": "minus_kD_vz", "expr": "-0.28*vz", "role": "drag"},
                          {"name": "minus_g", "expr": "-9.81", "role": "gravity"}],
      "ladder": [{"terms": {"⟨thrust_z⟩": 1.0, "⟨minus_kD_vz⟩": 1.5},
                  "intervals": {"⟨thrust_z⟩": [0.99, 1.01], "⟨minus_kD_vz⟩": [1.0, 2.0]},
                  "held": {}, "at_bound": {}}]}


def _flights(scales, seed=0, n=600):
    rng = np.random.default_rng(seed)
    k = len(scales)
    t = np.tile(np.arange(n) * 0.05, k)
    flight = np.repeat(np.arange(k), n)
    u = 4.9 + rng.normal(0, 0.8, n * k)
    vz = rng.normal(0, 1, n * k)
    a = np.repeat(np.asarray(scales, float), n)
    y = a * 2.0 * u - 1.5 * 0.28 * vz - 9.81 + rng.normal(0, 0.05, n * k)
    pred = 1.0 * 2.0 * u - 1.5 * 0.28 * vz - 9.81
    return {"u": u, "vz": vz}, y, pred, t, flight


def test_identified_constants_are_the_vehicle_constants_with_intervals():
    c = identified_constants(TR)
    assert set(c) == {"⟨thrust_z⟩", "⟨minus_kD_vz⟩"} and c["⟨thrust_z⟩"]["low"] == 0.99
    held = {**TR, "ladder": [{**TR["ladder"][0], "held": {"⟨minus_kD_vz⟩": 1.0}}]}
    assert set(identified_constants(held)) == {"⟨thrust_z⟩"}
    old = {**TR, "empirical_terms": [{k: v for k, v in f.items() if k != "role"} for f in TR["empirical_terms"]]}
    assert identified_constants(old) == {}


def test_a_flight_of_the_same_vehicle_holds_and_a_heavier_one_does_not():
    cols, y, pred, t, flight = _flights([1.0, 0.85])
    checks = check_constants(identified_constants(TR), cols, y, pred, t, flight, ["same", "heavier"])
    by = {(c.flight, c.label): c for c in checks}
    assert by["same", "⟨thrust_z⟩"].holds and by["same", "⟨minus_kD_vz⟩"].holds
    bad = by["heavier", "⟨thrust_z⟩"]
    assert not bad.holds and bad.p < 1e-6 and bad.low <= 0.85 <= bad.high
    line = constants_line(checks)
    assert line.startswith("VEHICLE CONSTANTS DO NOT HOLD on heavier: ⟨thrust_z⟩ differs")
    assert "heavier: ⟨thrust_z⟩ 0.85" in line and "DOES NOT HOLD" in line
    again = [ConstantCheck.from_dict(c.to_dict()) for c in checks]
    assert again == list(checks)
    good = constants_line([c for c in checks if c.flight == "same"])
    assert good.startswith("vehicle constants on this flight: every one holds")


def test_a_flight_too_short_or_lacking_the_signal_is_not_checked():
    cols, y, pred, t, flight = _flights([1.0], n=30)
    assert check_constants(identified_constants(TR), cols, y, pred, t, flight, ["short"]) == ()
    cols, y, pred, t, flight = _flights([1.0])
    assert check_constants(identified_constants(TR), {"vz": cols["vz"]}, y, pred, t, flight, ["f"]) == ()
