from droneid.report.document import Document, fmt, new_figure


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


def test_study_box_plot_labels_are_whole_and_fit_the_figure(tmp_path):
    from droneid.report.study import fig_study_box
    variants = {f"{sc}/{k}": {"scenario": sc, "prior_features": k,
                              "runs": [{"rmse_test": 0.1 + 0.01 * i} for i in range(3)]}
                for sc in ("baseline", "constrained") for k in (0, 1, 3)}
    fig = fig_study_box("vz_dot", {"variants": variants, "empirical": {"rmse_test": 0.2}})
    fig.savefig(tmp_path / "box.png")  # draws (and lays out) the figure
    ax = fig.axes[0]
    labels = [lb.get_text() for lb in ax.get_xticklabels()]
    assert labels[0] == "baseline\nno prior" and labels[-1] == "constrained\n3 prior features"
    r = fig.canvas.get_renderer() if hasattr(fig.canvas, "get_renderer") else fig._get_renderer()
    boxes = [lb.get_window_extent(r) for lb in ax.get_xticklabels()]
    assert all(a.x1 <= b.x0 for a, b in zip(boxes, boxes[1:]))  # neighbours do not overlap
    assert boxes[0].x0 >= 0 and boxes[-1].x1 <= fig.bbox.width
    assert "(m/s²)" in ax.get_ylabel()
