"""write_report_set: a report folder always holds one run's files; report.md escapes its text."""
import json
import os
import re
import subprocess
import sys
import textwrap

import pytest

from droneid.errors import ConfigError
from droneid.report.document import INCOMPLETE, MANIFEST, Document, md_escape, write_report_set


def test_fresh_folder_gets_the_set_and_a_manifest(tmp_path):
    d = tmp_path / "rep"
    paths = write_report_set(d, {"result.json": "{}\n", "a.png": b"\x89PNG"})
    assert {p.name for p in d.iterdir()} == {"result.json", "a.png", MANIFEST}
    assert json.loads((d / MANIFEST).read_text())["files"] == ["a.png", "result.json"]
    assert paths["a.png"].read_bytes() == b"\x89PNG"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp folders left


def test_a_second_run_replaces_the_whole_set(tmp_path):
    d = tmp_path / "rep"
    write_report_set(d, {"result.json": "old", "old_fig.png": b"old"})
    write_report_set(d, {"result.json": "new", "new_fig.png": b"new"})
    assert {p.name for p in d.iterdir()} == {"result.json", "new_fig.png", MANIFEST}
    assert (d / "result.json").read_text() == "new"
    assert not [p for p in tmp_path.iterdir() if p.name != "rep"]


def test_a_folder_with_other_files_is_written_in_place_and_keeps_them(tmp_path):
    (tmp_path / "flight.bin").write_bytes(b"log")
    write_report_set(tmp_path, {"report.md": "one", "fig1.png": b"1"})
    write_report_set(tmp_path, {"report.md": "two", "fig2.png": b"2"})
    names = {p.name for p in tmp_path.iterdir()}
    assert names == {"flight.bin", "report.md", "fig2.png", MANIFEST}  # fig1 of run one is gone
    assert (tmp_path / "flight.bin").read_bytes() == b"log"


def test_bad_names_and_file_targets_are_refused(tmp_path):
    with pytest.raises(ConfigError):
        write_report_set(tmp_path / "r", {"../escape.md": "x"})
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError):
        write_report_set(tmp_path / "file", {"a.md": "x"})


_KILLED_WRITER = textwrap.dedent("""
    import os, sys
    import droneid.core.io_util as io
    from droneid.report.document import write_report_set
    real, count = io.atomic_write_bytes, [0]
    def dying(path, data):
        count[0] += 1
        if count[0] == 3:          # killed after two files of the new set
            os._exit(9)
        return real(path, data)
    import droneid.report.document as rep
    rep.atomic_write_bytes = dying
    write_report_set(sys.argv[1], {"result.json": "new", "report.md": "new", "report.html": "new",
                                   "new.png": b"new"})
""")


@pytest.mark.parametrize("foreign", [False, True])
def test_a_killed_run_never_leaves_a_mixed_folder(tmp_path, foreign):
    d = tmp_path / "rep"
    if foreign:
        d.mkdir()
        (d / "notes.txt").write_text("mine")
    write_report_set(d, {"result.json": "old", "report.md": "old", "report.html": "old", "old.png": b"old"})
    env = dict(os.environ, PYTHONPATH=os.getcwd())
    r = subprocess.run([sys.executable, "-c", _KILLED_WRITER, str(d)], env=env)
    assert r.returncode == 9
    names = {p.name for p in d.iterdir()} - {"notes.txt"}
    contents = {(d / n).read_bytes() for n in names - {MANIFEST, INCOMPLETE}}
    if foreign:   # written in place: the marker says so and no file of the old run is left
        assert INCOMPLETE in names and b"old" not in contents
        assert (d / "notes.txt").read_text() == "mine"
    else:         # swapped: the folder is still the old run's, complete
        assert names == {"result.json", "report.md", "report.html", "old.png", MANIFEST}
        assert contents == {b"old"}
    write_report_set(d, {"result.json": "third"})  # the next run cleans up
    assert INCOMPLETE not in {p.name for p in d.iterdir()}


def test_document_write_with_data_returns_the_old_keys(tmp_path):
    paths = Document("T").paragraph("p").write(tmp_path / "o", "report", data={"result.json": {"x": float("nan")}})
    assert paths["json"].name == "result.json" and json.loads(paths["json"].read_text()) == {"x": None}
    assert paths["md"].name == "report.md" and paths["html"].name == "report.html"


# -- Markdown escaping ----------------------------------------------------------------------------

def test_markdown_escapes_html_and_links_in_every_block():
    evil = "<img src=x onerror=alert(1)>.csv"
    doc = (Document(evil).heading(evil).paragraph(f"Training logs: {evil}, [a](javascript:x)")
           .table(["file"], [[evil]]))
    md = doc.markdown()
    assert "<img" not in md and "&lt;img src=x onerror=alert(1)>.csv" in md
    assert not re.search(r"(?<!\\)\]\(javascript", md) and "\\[a\\](javascript" in md


def test_markdown_escape_keeps_ordinary_text_readable():
    assert md_escape("vx_dot rmse 0.05 m/s² (-0.5)") == "vx_dot rmse 0.05 m/s² (-0.5)"
    assert md_escape("# 1. _x_ *y*") == "\\# 1. \\_x\\_ \\*y\\*"
    assert md_escape("line\n- item") == "line\n\\- item"
    # arrows and comparisons read as they are; only what could open markup is an entity
    assert md_escape("CV RMSE 1.5 -> 1.4 (< 1 %), a & b") == "CV RMSE 1.5 -> 1.4 (< 1 %), a & b"
    assert md_escape("a <b> &amp; </i> <!-- x") == "a &lt;b> &amp;amp; &lt;/i> &lt;\\!-- x"


def test_code_blocks_cannot_be_closed_by_their_content():
    md = Document("T").code("a\n```\n<b>").markdown()
    assert "````\na\n```\n<b>\n````" in md
