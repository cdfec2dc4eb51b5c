"""A log format is one new module: a plug-in reader placed on the ``parsers`` package path is
detected by content, reachable by ``--format`` from the CLI, and a name clash is refused."""
from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

import parsers
from droneid.cli import main
from droneid.errors import ConfigError

PLUGIN = textwrap.dedent('''
    """A toy text format: the line XYZLOG v1, then rows of t,x,y,z (s, m, ENU)."""
    import numpy as np
    from parsers._build import FlightBuilder
    from parsers._registry import Reader

    def read_xyz(path, scale=None):
        rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        b = FlightBuilder(path, "xyzlog")
        k = float(scale or 1.0)
        b.add_many(rows[:, 0], {"x": k * rows[:, 1], "y": k * rows[:, 2], "z": k * rows[:, 3]},
                   dict.fromkeys("xyz", "m"), "XYZ rows")
        return b.build()

    def sniff(head):
        return head.startswith(b"XYZLOG v1")

    READER = Reader("xyzlog", read_xyz, sniff, order=10, extensions=(".xyz",), options=("scale",))
''')


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    d = tmp_path / "plugins"
    d.mkdir()
    monkeypatch.setattr(parsers, "__path__", [*parsers.__path__, str(d)])
    parsers.clear_cache()
    yield d
    parsers.clear_cache()
    sys.modules.pop("parsers.xyz_log", None)


@pytest.fixture
def xyz_log(tmp_path):
    t = np.arange(0, 5, 0.05)
    p = tmp_path / "hover.dat"            # no telling extension: the content decides
    rows = "\n".join(f"{a:.3f},{np.sin(a):.4f},{np.cos(a):.4f},{1 + 0.1 * a:.4f}" for a in t)
    p.write_text("XYZLOG v1\n" + rows + "\n")
    return p


def test_one_new_module_is_a_new_format(plugin_dir, xyz_log, capsys):
    (plugin_dir / "xyz_log.py").write_text(PLUGIN)
    assert "xyzlog" in parsers.READERS and "xyzlog" in parsers.FORMATS
    assert parsers.detect_format(xyz_log) == "xyzlog"
    f = parsers.read_flight(xyz_log)
    assert f.provenance.format == "xyzlog"
    assert np.isclose(f["z"].values[-1], 1 + 0.1 * 4.95, atol=1e-3)
    assert np.isclose(parsers.read_flight(xyz_log, scale=2.0)["z"].values[0], 2.0, atol=1e-3)
    with pytest.raises(ConfigError, match="sysid"):      # an option of another format is refused
        parsers.read_flight(xyz_log, sysid=1)
    code = main(["inspect", str(xyz_log), "--format", "xyzlog"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "xyzlog" in out


def test_without_the_module_the_format_is_unknown(xyz_log, capsys):
    parsers.clear_cache()
    code = main(["inspect", str(xyz_log)])
    _, err = capsys.readouterr()
    assert code == 2 and "unrecognised log format" in err and len(err.strip().splitlines()) == 1


def test_a_name_clash_names_both_modules(plugin_dir):
    (plugin_dir / "xyz_log.py").write_text(PLUGIN.replace('Reader("xyzlog"', 'Reader("tlog"'))
    with pytest.raises(ConfigError, match=r"'tlog' is defined twice: in .*mavlink_log\.py and in .*xyz_log\.py"):
        parsers.detect_format(__file__)
