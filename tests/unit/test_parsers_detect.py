"""Format detection, the reader registry, and bad input for every format (files made in tmp_path).
The same damage on the real logs: tests/real_logs/test_detect_real.py."""
from __future__ import annotations

import importlib
import inspect
from pathlib import Path

import numpy as np
import pytest

from droneid.errors import ConfigError, LogFormatError
from parsers import FORMATS, READERS, Reader, detect_format, get_reader, read_flight


def test_every_registered_reader_is_reachable_by_name():
    """The shipped formats are registered; a new reader plug-in passes without editing this."""
    assert {"dataflash", "tlog", "ulog", "mcap", "motive_csv", "csv"} <= set(FORMATS)
    assert set(FORMATS) == set(READERS) and len(FORMATS) == len(READERS)
    for name in READERS:
        assert get_reader(name) is READERS[name].read


@pytest.mark.parametrize("name", FORMATS)
def test_every_registered_reader_meets_the_plugin_contract(name):
    """What parsers/_registry.py asks of a reader plug-in: its module exports a Reader as
    ``READER`` or in ``READERS``, under its format name, with ``read(path, **options)``, a
    ``sniff(head) -> bool``, an integer ``order``, lower-case dotted ``extensions`` and a
    one-line ``description``."""
    r = READERS[name]
    assert isinstance(r, Reader) and r.name == name
    mod = importlib.import_module(f"parsers.{Path(r.module).stem}")
    exported = [getattr(mod, "READER", None), *getattr(mod, "READERS", ())]
    assert any(isinstance(x, Reader) and x.name == name for x in exported), r.module
    assert callable(r.read) and callable(r.sniff)
    params = inspect.signature(r.read).parameters
    assert params and next(iter(params.values())).kind in (
        inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)  # read(path, ...)
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    for opt in r.options:
        assert isinstance(opt, str) and (takes_any or opt in params), (name, opt)
    for head in (bytes(64), b"t,x\n0,1\n", b"ULog\x01\x12\x35\x01" + bytes(40)):
        assert isinstance(r.sniff(head), bool), (name, head)
    assert isinstance(r.order, int)
    assert isinstance(r.extensions, tuple)
    assert all(e.startswith(".") and e == e.lower() for e in r.extensions), r.extensions
    assert isinstance(r.description, str) and r.description.strip() and "\n" not in r.description


def test_unknown_format_name_suggests_the_nearest():
    with pytest.raises(ConfigError, match="did you mean 'ulog'"):
        get_reader("ulgo")
    with pytest.raises(ConfigError, match="unknown log format"):
        read_flight(__file__, format="nope")


@pytest.mark.parametrize("head, fmt", [
    (b"ULog\x01\x12\x35\x01" + bytes(40), "ulog"),
    (b"\x89MCAP0\r\n" + bytes(40), "mcap"),
    (b"\xa3\x95\x80\x80YFMT" + bytes(40), "dataflash"),
    (b"Format Version,1.23,Take Name,x\r\n\r\n,Type,Rigid Body\r\n", "motive_csv"),
    (b"t,x,y,z\n0,1,2,3\n", "csv"),
])
def test_detect_by_content_not_extension(tmp_path, head, fmt):
    p = tmp_path / "log.weird"           # no telling extension
    p.write_bytes(head)
    assert detect_format(p) == fmt


def test_detect_tlog_by_timestamp_and_magic(tmp_path):
    from tlog_fixture import tlog_bytes
    p = tmp_path / "x.bin"               # misleading extension: content wins
    p.write_bytes(tlog_bytes([("heartbeat", 0.0, {})]))
    assert detect_format(p) == "tlog"


def test_empty_file_is_one_line_error(tmp_path):
    p = tmp_path / "empty.bin"
    p.write_bytes(b"")
    with pytest.raises(LogFormatError) as ei:
        read_flight(p)
    assert str(p) in str(ei.value) and "empty" in str(ei.value) and "\n" not in str(ei.value)


def test_random_bytes_are_rejected(tmp_path):
    p = tmp_path / "noise.tlog"
    p.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(LogFormatError, match="unrecognised log format"):
        read_flight(p)


def test_missing_file_is_oserror(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_flight(tmp_path / "nope.bin")


def test_option_for_another_format_is_rejected(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("t,x\n0,1\n0.1,2\n")
    with pytest.raises(ConfigError, match="topics"):
        read_flight(p, topics={"pose": "/x"})
