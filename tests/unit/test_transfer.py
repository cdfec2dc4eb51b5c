"""predict's check of a result's vehicle constants on other flights (droneid.use.transfer): a flight
of the same vehicle keeps them, one whose thrust per unit mass differs (another vehicle, a
payload) is flagged, a constant the flight does not excite or a flight the result was trained on
is not checked, several training flights give a new flight the room their spread says, and a
result written before term roles were recorded has nothing to check."""
from __future__ import annotations

import json
import math

import numpy as np

from droneid.core.io_util import json_text
from droneid.use.transfer import ConstantCheck, check_constants, constants_line, identified_constants

TR = {"empirical_terms": [{"name": "thrust_z", "expr": "2.0*u", "role": "thrust"},
                          {"name": "minus_kD_vz", "expr": "-0.28*vz", "role": "drag"},
                          {"name": "minus_g", "expr": "-9.81", "role": "gravity"}],
      "ladder": [{"terms": {"⟨thrust_z⟩": 1.0, "⟨minus_kD_vz⟩": 1.5},
                  "intervals": {"⟨thrust_z⟩": [0.99, 1.01], "⟨minus_kD_vz⟩": [1.0, 2.0]},
                  "held": {}, "at_bound": {}}]}


def _flights(scales, seed=0, n=600, vz_sd=1.0):
    rng = np.random.default_rng(seed)
    k = len(scales)
    t = np.tile(np.arange(n) * 0.05, k)
    flight = np.repeat(np.arange(k), n)
    u = 4.9 + rng.normal(0, 0.8, n * k)
    vz = rng.normal(0, vz_sd, n * k)
    a = np.repeat(np.asarray(scales, float), n)
    y = a * 2.0 * u - 1.5 * 0.28 * vz - 9.81 + rng.normal(0, 0.05, n * k)
    pred = 1.0 * 2.0 * u - 1.5 * 0.28 * vz - 9.81
    return {"u": u, "vz": vz}, y, pred, t, flight


def test_identified_constants_are_what_a_new_flight_of_the_vehicle_gives():
    c = identified_constants(TR)
    assert set(c) == {"⟨thrust_z⟩", "⟨minus_kD_vz⟩"}
    one = c["⟨thrust_z⟩"]
    assert one["flights"] == 1 and one["df"] == math.inf and math.isclose(one["se"], 0.01 / 1.959964)
    held = {**TR, "ladder": [{**TR["ladder"][0], "held": {"⟨minus_kD_vz⟩": 1.0}}]}
    assert set(identified_constants(held)) == {"⟨thrust_z⟩"}
    old = {**TR, "empirical_terms": [{k: v for k, v in f.items() if k != "role"} for f in TR["empirical_terms"]]}
    assert identified_constants(old) == {}
    # three training flights that differ: a new flight varies about their mean by se_mu and tau
    many = {**TR, "constancy": {"thrust_z": {"unit": "flight", "per_flight": {"a": [0.97, 0.96, 0.98],
            "b": [1.0, 0.99, 1.01], "c": [1.03, 1.02, 1.04]}, "between": [0.92, 1.08], "tau": 0.03}}}
    m = identified_constants(many)["⟨thrust_z⟩"]
    assert m["flights"] == 3 and m["df"] == 2 and math.isclose(m["value"], 1.0)
    assert m["se"] > 0.03 and m["se"] > one["se"]


def test_a_flight_of_the_same_vehicle_holds_and_a_heavier_one_does_not():
    cols, y, pred, t, flight = _flights([1.0, 0.85])
    checks = check_constants(identified_constants(TR), cols, y, pred, t, flight, ["same", "heavier"])
    by = {(c.flight, c.label): c for c in checks}
    assert by["same", "⟨thrust_z⟩"].holds and by["same", "⟨minus_kD_vz⟩"].holds
    bad = by["heavier", "⟨thrust_z⟩"]
    assert bad.holds is False and bad.p < 1e-6 and bad.low <= 0.85 <= bad.high
    line = constants_line(checks)
    assert line.startswith("VEHICLE CONSTANTS DO NOT HOLD on heavier: ⟨thrust_z⟩ differs")
    assert "heavier: ⟨thrust_z⟩ 0.85" in line and "DOES NOT HOLD" in line
    assert "tilts" not in line           # a vertical thrust scale: no word on tilt
    assert "one training flight" in line
    assert [ConstantCheck.from_dict(json.loads(json_text(c.to_dict()))) for c in checks if c.holds is not None] \
        == [c for c in checks if c.holds is not None]
    good = constants_line([c for c in checks if c.flight == "same"])
    assert good.startswith("vehicle constants on this flight: every one tested holds")


def test_the_spread_of_several_training_flights_is_room_for_a_new_one():
    """A flight 3 % off is flagged against one training flight known to ±1 %, not against three
    training flights that themselves spread 3 %."""
    cols, y, pred, t, flight = _flights([1.03])
    one = check_constants(identified_constants(TR), cols, y, pred, t, flight, ["f"])
    assert [c.holds for c in one if c.label == "⟨thrust_z⟩"] == [False]
    many = {**TR, "constancy": {"thrust_z": {"unit": "flight", "per_flight": {"a": [0.97, 0.96, 0.98],
            "b": [1.0, 0.99, 1.01], "c": [1.03, 1.02, 1.04]}, "between": [0.92, 1.08], "tau": 0.03}}}
    again = check_constants(identified_constants(many), cols, y, pred, t, flight, ["f"])
    assert [c.holds for c in again if c.label == "⟨thrust_z⟩"] == [True]


def test_what_cannot_be_checked_is_said_not_flagged():
    # drag on a flight that does not move vertically: not identifiable there
    cols, y, pred, t, flight = _flights([1.0], vz_sd=0.0)
    c = {x.label: x for x in check_constants(identified_constants(TR), cols, y, pred, t, flight, ["hover"])}
    assert c["⟨minus_kD_vz⟩"].holds is None and "not identifiable" in c["⟨minus_kD_vz⟩"].why
    assert c["⟨thrust_z⟩"].holds is True
    # a training flight of the result is not tested against itself
    cols, y, pred, t, flight = _flights([0.8])
    same = check_constants(identified_constants(TR), cols, y, pred, t, flight, ["sq1"], trained=("sq1",))
    assert all(x.holds is None and "training flight" in x.why for x in same)
    assert constants_line(same).startswith("vehicle constants not checked on this flight")
    cols, y, pred, t, flight = _flights([1.0], n=30)
    short = check_constants(identified_constants(TR), cols, y, pred, t, flight, ["short"])
    assert all(x.holds is None and "fewer than" in x.why for x in short)
    cols, y, pred, t, flight = _flights([1.0])
    assert check_constants(identified_constants(TR), {"vz": cols["vz"]}, y, pred, t, flight, ["f"]) == ()


def test_a_flight_that_pushes_a_constant_through_its_bound_is_tested_not_set_aside():
    """Each flight is fitted without the physics bounds (constancy.unit_bounds), as the training
    flights' units are: a flight whose vertical drag pushes through 0 (here it accelerates with
    its vertical speed) was read at the bound 0 and called "not identifiable"; it is a flight
    that DOES NOT HOLD the drag. The width rule reads the expected value, not the flight's own."""
    cols, y, pred, t, flight = _flights([1.0])
    y = y + 2.0 * 0.28 * cols["vz"]                    # the drag scale 1.5 -> -0.5
    c = {x.label: x for x in check_constants(identified_constants(TR), cols, y, pred, t, flight, ["odd"])}
    drag = c["⟨minus_kD_vz⟩"]
    assert drag.value < -0.3 and drag.high < 0 and drag.holds is False, drag
    assert c["⟨thrust_z⟩"].holds is True
