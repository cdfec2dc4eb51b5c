import numpy as np
import pytest

from droneid.errors import DataError, DroneIdError, MissingSignalError
from droneid.logs.flight import Diagnostics, Flight, Provenance, Signal, canonical_unit, is_canonical


def _flight():
    t = np.linspace(0, 10, 101)
    return Flight(
        {"vx": Signal("vx", t, np.sin(t), "m/s", "TEST.vx"),
         "roll": Signal("roll", t[::2], 0.1 * t[::2], "rad", "TEST.roll")},
        Provenance(files=("a.bin",), format="test"),
        segments={"armed": [(1.0, 9.0)]},
    )


def test_signal_rejects_non_increasing_time():
    with pytest.raises(DataError):
        Signal("x", [0, 1, 1], [1, 2, 3], "m")


def test_signal_clean_counts_what_it_drops():
    s, dropped = Signal.clean("x", [0, 1, 1, 0.5, 2, 3], [0, 1, 2, 3, np.nan, 5], "m")
    np.testing.assert_array_equal(s.t, [0, 1, 3])
    assert dropped == {"non-finite values": 1, "duplicate time stamps": 1, "backwards time stamps": 1}


def test_flight_access_and_missing_signal_suggestion():
    f = _flight()
    assert f["vx"].unit == "m/s"
    assert f.has("vx", "roll") and not f.has("vy")
    with pytest.raises(MissingSignalError, match="did you mean 'vx'") as ei:
        f["vxx"]
    assert isinstance(ei.value, KeyError) and isinstance(ei.value, DroneIdError)
    assert "a.bin" in str(ei.value)


def test_flight_is_immutable_and_derivations_copy():
    f = _flight()
    with pytest.raises(ValueError):
        f["vx"].values[0] = 3.0
    g = f.with_signals(Signal("vy", [0, 1], [0, 0], "m/s"), note="vy added")
    assert "vy" in g and "vy" not in f and g.provenance.notes == ("vy added",)
    h = f.shifted(2.0)
    assert h["vx"].t[0] == 2.0 and h.segments["armed"] == ((3.0, 11.0),)
    assert f.between(2, 4)["vx"].t.min() >= 2


def test_summary_has_the_inspect_schema():
    s = _flight().summary()
    assert s["format"] == "test" and s["duration_s"] == 10.0
    names = [x["name"] for x in s["signals"]]
    assert names == ["vx", "roll"]  # canonical order
    vx = s["signals"][0]
    assert set(vx) >= {"name", "unit", "rate_hz", "count", "start_s", "end_s", "source"}
    assert vx["rate_hz"] == pytest.approx(10.0) and vx["count"] == 101


def test_diagnostics_add():
    d = Diagnostics().add({"bad crc": 2}).add({"bad crc": 1, "x": 0}, ["gap of 2 s"])
    assert d.skipped == {"bad crc": 3} and d.total_skipped == 3 and d.warnings == ("gap of 2 s",)


def test_canonical_names():
    assert is_canonical("motor4") and is_canonical("battery_voltage") and not is_canonical("motor0")
    assert canonical_unit("vz") == "m/s" and canonical_unit("motor2") == "1"
    with pytest.raises(MissingSignalError):
        canonical_unit("speed")


def test_clean_drops_a_lone_damaged_stamp_not_everything_after_it():
    """One flipped bit in a stamp (2**25 s ahead) once made every later sample 'backwards'."""
    import numpy as np
    from droneid.logs.flight import Signal
    t = np.arange(100) * 0.01
    t[40] += 2.0 ** 25
    s, dropped = Signal.clean("x", t, np.arange(100.0), "m")
    assert dropped == {"out-of-sequence time stamps": 1}
    assert len(s) == 99 and s.end_s == 0.99 and 40.0 not in s.values
    t2 = np.arange(10) * 0.1
    t2[5] = t2[4]                                    # a duplicate is still a duplicate
    _, d2 = Signal.clean("x", t2, np.zeros(10), "m")
    assert d2 == {"duplicate time stamps": 1}


def test_a_flight_survives_pickling_for_a_worker_process():
    # identify sends flights to worker processes (the offset search): the same signals, checked
    # and read-only, and the same provenance, diagnostics, segments and events
    import pickle

    from droneid.logs.flight import Event
    t = np.linspace(0.0, 1.0, 11)
    f = Flight({"vx": Signal("vx", t, np.sin(t), "m/s", "LOCAL_POSITION_NED.vx")},
               diagnostics=Diagnostics({"bad crc": 2}, ("a gap",)),
               segments={"in_flight": [(0.1, 0.9)]}, events=(Event(0.5, "mode", "GUIDED"),))
    g = pickle.loads(pickle.dumps(f))
    assert g.provenance == f.provenance and g.diagnostics.warnings == ("a gap",)
    assert np.array_equal(g["vx"].values, f["vx"].values) and g["vx"].source == "LOCAL_POSITION_NED.vx"
    assert not g["vx"].values.flags.writeable and not g["vx"].t.flags.writeable
    assert dict(g.diagnostics.skipped) == {"bad crc": 2} and g.segments == f.segments
    assert g.events == f.events
    # every field goes through (a field added later must not be dropped silently)
    from dataclasses import fields
    for obj, copy in ((f, g), (f["vx"], g["vx"]), (f.diagnostics, g.diagnostics)):
        for fl in fields(obj):
            a, b = getattr(obj, fl.name), getattr(copy, fl.name)
            if isinstance(a, np.ndarray):
                assert np.array_equal(a, b), fl.name
            elif fl.name != "signals":
                assert a == b, fl.name


def test_a_flight_given_twice_is_read_once_and_a_test_flight_may_not_be_a_training_flight():
    from droneid.logs.flight import distinct_flights, fingerprint
    a = _flight()
    copy = Flight(a.signals, Provenance(files=("copy_of_a.bin",), format="test"))   # the same data, another file
    t = a["vx"].t
    other = a.with_signals(Signal("vx", t, np.sin(t) + np.where(t == t[50], 1e-9, 0.0), "m/s"))  # one sample differs
    assert fingerprint(a) == fingerprint(copy) != fingerprint(other)
    train, test, notes = distinct_flights([a, copy, other], [])
    assert train == [a, other] and test == []
    assert notes == ["copy_of_a.bin: the same data as the training flight a.bin: read once"]
    with pytest.raises(DataError, match="copy_of_a.bin: this test flight is the same data as the training flight a.bin"):
        distinct_flights([a], [copy])
    assert distinct_flights([a], [other])[1] == [other]


def test_predict_knows_a_training_flight_by_its_data_whatever_its_file_is_called():
    from droneid.identify.result import flight_provenance
    from droneid.logs.flight import fingerprint
    from droneid.use.predict import _trained, trained_fingerprints
    a = _flight()
    prov = {"train": flight_provenance([a])}
    assert prov["train"][0]["fingerprint"] == fingerprint(a) and prov["train"][0]["files"] == ("a.bin",)
    models = {"_trained": ("a",), "_trained_data": trained_fingerprints(prov)}
    copy = Flight(a.signals, Provenance(files=("renamed.bin",), format="test"))
    t = a["vx"].t
    new = a.with_signals(Signal("vx", t, np.cos(t), "m/s"))
    assert _trained(models, ["renamed", "new"], [copy, new]) == ("a", "renamed")
    assert trained_fingerprints({"train": [{"files": ["old.bin"]}]}) == frozenset()   # a result before fingerprints
