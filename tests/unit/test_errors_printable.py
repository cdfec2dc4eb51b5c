"""Error lines escape non-printable characters taken from a file (issue 29, item 3): the fuzz
found "Unsupported format char: '\\x07'" printed with the raw control character."""
from __future__ import annotations

from droneid.cli import main
from droneid.errors import ConfigError, DataError, LogFormatError, MissingSignalError, printable

from dataflash_fixture import DataFlashWriter


def test_printable_escapes_control_and_format_characters():
    assert printable("a\x07b\nc\u200bd\x1b[31m é") == "a\\x07b\\nc\\u200bd\\x1b[31m é"
    assert str(LogFormatError("f\x00.bin", "bad \x7f")) == "f\\x00.bin: bad \\x7f"
    assert str(MissingSignalError("v\x01", ["vx"])).startswith("signal 'v\\x01' is not available")
    assert "\n" not in str(DataError("two\nlines")) and "\t" not in str(ConfigError("a\tb"))


def test_cli_error_line_has_no_control_character(tmp_path, capsys):
    w = DataFlashWriter()
    w.fmt("ATT", "Qff", "TimeUS,Roll,Pitch")
    for i in range(50):
        w.add("ATT", i * 100_000, 0.1, 0.2)
    data = bytearray(w.bytes())
    i = data.find(b"Qff")
    data[i + 1] = 0x07                                  # a control character as a format char
    p = tmp_path / "bad.bin"
    p.write_bytes(bytes(data))
    assert main(["inspect", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "\\x07" in err
    assert not any(not c.isprintable() for c in err.rstrip("\n")), repr(err)
