from droneid.reporting import Document, fmt, new_figure


def test_document_writes_md_html_and_pngs(tmp_path):
    fig = new_figure()
    ax = fig.add_subplot()
    ax.plot([0, 1], [1, 0])
    doc = Document("Title").heading("Errors").table(["model", "rmse"], [["a|b", fmt(0.123456)]])
    doc.paragraph("x < y & z").figure(fig, "fig1", "a line")
    paths = doc.write(tmp_path / "out")
    md = paths["md"].read_text()
    html = paths["html"].read_text()
    assert "| a\\|b | 0.1235 |" in md and "![a line](fig1.png)" in md
    assert "data:image/png;base64," in html and "x &lt; y &amp; z" in html
    assert (tmp_path / "out" / "fig1.png").read_bytes()[:4] == b"\x89PNG"


def test_fmt():
    assert fmt(None) == "—" and fmt(float("nan")) == "—" and fmt(1234567.0, 3) == "1.23e+06"
