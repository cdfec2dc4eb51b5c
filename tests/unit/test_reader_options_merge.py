"""How predict combines the reader options a result recorded with the ones given to it
(:func:`droneid.commands._common.merged_log_options`): given over recorded, map entries by name,
recorded options the log's reader does not take left out (given ones kept, to be refused)."""
from __future__ import annotations

import pytest

from droneid.commands._common import merged_log_options, options_text
from droneid.errors import DataError
from droneid.use.predict import _reader_options

NONE = {"format": None, "topics": None, "body": None, "column_map": None, "sysid": None, "vehicle": None}


@pytest.fixture()
def csv_log(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("t,pos_e,vel_e\n0,0,0\n0.01,0,0\n", encoding="utf-8")
    return p


@pytest.fixture()
def tlog(tmp_path):
    from droneid.simulation.simulator import simulate
    from parsers.tlog_writer import write_tlog
    p = tmp_path / "a.tlog"
    write_tlog(simulate(path="hover", duration_s=1, seed=0).flight, p)
    return p


def test_recorded_options_apply_when_none_are_given(csv_log):
    rec = {"column_map": {"x": "pos_e", "vx": "vel_e"}, "vehicle": "multirotor"}
    assert merged_log_options(rec, NONE, csv_log) == rec


def test_given_entries_replace_recorded_entries_of_the_same_name(csv_log):
    rec = {"column_map": {"x": "pos_e", "vx": "vel_e"}, "vehicle": "multirotor"}
    given = {**NONE, "column_map": {"vx": "speed_e"}, "vehicle": "vtol"}
    assert merged_log_options(rec, given, csv_log) == {"column_map": {"x": "pos_e", "vx": "speed_e"},
                                                       "vehicle": "vtol"}


def test_recorded_options_the_reader_does_not_take_are_left_out(tlog):
    rec = {"column_map": {"x": "pos_e"}, "body": "b1", "vehicle": "multirotor", "sysid": 1}
    assert merged_log_options(rec, NONE, tlog) == {"vehicle": "multirotor", "sysid": 1}


def test_given_options_are_kept_even_where_they_do_not_apply(tlog):
    """read_flight refuses them with its own line: a given option is never dropped silently."""
    given = {**NONE, "column_map": {"x": "pos_e"}}
    assert merged_log_options({"column_map": {"y": "pos_n"}}, given, tlog) == {"column_map": {"y": "pos_n", "x": "pos_e"}}


def test_an_unreadable_path_keeps_the_options_for_read_flight_to_refuse(tmp_path):
    rec = {"column_map": {"x": "pos_e"}}
    assert merged_log_options(rec, NONE, tmp_path / "missing.csv") == rec


def test_options_text_gives_the_command_line_words():
    assert options_text({"column_map": {"x": "pos_e"}, "body": "b1", "sysid": None, "topics": {}}) == \
        "--column x=pos_e --body b1"


@pytest.mark.parametrize("bad", [{"sysid": True}, {"body": 3}, {"topics": {"pose": 1}}, {"nope": "x"}, "x"])
def test_a_damaged_record_is_a_data_error(bad):
    with pytest.raises(DataError, match="reader_options"):
        _reader_options("r.json", bad)


def test_unset_options_are_left_out_of_the_record():
    assert _reader_options("r.json", {**NONE, "column_map": {}, "vehicle": "rover"}) == {"vehicle": "rover"}
    assert _reader_options("r.json", None) == {}
