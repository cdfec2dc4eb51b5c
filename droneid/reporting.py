"""Building blocks for human reports: one document rendered as Markdown and self-contained HTML.

A :class:`Document` collects headings, paragraphs, tables and matplotlib figures; ``write(dir,
stem)`` saves each figure as PNG, the Markdown (figures linked) and the HTML (figures embedded
as base64, so the file opens anywhere), all atomically. Rendering is pure: no printing.
"""
from __future__ import annotations

import base64
import html
import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .io_util import atomic_write_bytes, atomic_write_text

__all__ = ["Document", "new_figure", "fmt"]


def new_figure(width_in: float = 7.0, height_in: float = 3.6):
    """A matplotlib figure on the non-interactive Agg canvas (no display needed)."""
    from matplotlib.figure import Figure
    return Figure(figsize=(width_in, height_in), dpi=110, layout="constrained")


def fmt(x, sig: int = 4) -> str:
    """A number with ``sig`` significant figures; '—' for None/nan."""
    if x is None:
        return "—"
    try:
        xf = float(x)
    except (TypeError, ValueError):
        return str(x)
    if xf != xf:
        return "—"
    return f"{xf:.{sig}g}"


@dataclass
class _Figure:
    name: str
    png: bytes
    caption: str


@dataclass
class Document:
    """An ordered list of blocks; see module docstring."""
    title: str
    blocks: list = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> "Document":
        self.blocks.append(("h", level, text))
        return self

    def paragraph(self, text: str) -> "Document":
        self.blocks.append(("p", text))
        return self

    def code(self, text: str) -> "Document":
        self.blocks.append(("code", text))
        return self

    def table(self, header: Sequence[str], rows: Sequence[Sequence]) -> "Document":
        self.blocks.append(("table", [str(h) for h in header], [[str(c) for c in r] for r in rows]))
        return self

    def png(self, data: bytes, name: str, caption: str = "") -> "Document":
        """Add an already rendered PNG; ``name`` becomes ``name.png`` beside the report."""
        self.blocks.append(("fig", _Figure(name, bytes(data), caption)))
        return self

    def figure(self, fig, name: str, caption: str = "") -> "Document":
        """Add a matplotlib figure; ``name`` becomes ``name.png`` beside the report."""
        buf = io.BytesIO()
        fig.savefig(buf, format="png")
        self.blocks.append(("fig", _Figure(name, buf.getvalue(), caption)))
        return self

    # -- rendering ----------------------------------------------------------------------------
    def markdown(self) -> str:
        out = [f"# {self.title}", ""]
        for b in self.blocks:
            if b[0] == "h":
                out += ["#" * b[1] + " " + b[2], ""]
            elif b[0] == "p":
                out += [b[1], ""]
            elif b[0] == "code":
                out += ["```", b[1], "```", ""]
            elif b[0] == "table":
                out.append("| " + " | ".join(b[1]) + " |")
                out.append("|" + "---|" * len(b[1]))
                out += ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in b[2]]
                out.append("")
            elif b[0] == "fig":
                out += [f"![{b[1].caption or b[1].name}]({b[1].name}.png)", ""]
                if b[1].caption:
                    out += [f"*{b[1].caption}*", ""]
        return "\n".join(out)

    def html(self) -> str:
        e = html.escape
        out = ["<!DOCTYPE html>", "<html><head><meta charset='utf-8'>", f"<title>{e(self.title)}</title>",
               "<style>body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em}"
               "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:.25em .6em;"
               "text-align:right}th{background:#eee}td:first-child,th:first-child{text-align:left}"
               "pre{background:#f6f6f6;padding:.6em;overflow-x:auto}img{max-width:100%}"
               "figcaption{color:#555;font-size:90%}</style></head><body>", f"<h1>{e(self.title)}</h1>"]
        for b in self.blocks:
            if b[0] == "h":
                out.append(f"<h{b[1]}>{e(b[2])}</h{b[1]}>")
            elif b[0] == "p":
                out.append(f"<p>{e(b[1])}</p>")
            elif b[0] == "code":
                out.append(f"<pre>{e(b[1])}</pre>")
            elif b[0] == "table":
                out.append("<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in b[1]) + "</tr>")
                out += ["<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in b[2]]
                out.append("</table>")
            elif b[0] == "fig":
                data = base64.b64encode(b[1].png).decode("ascii")
                out.append(f"<figure><img alt='{e(b[1].name)}' src='data:image/png;base64,{data}'>"
                           f"<figcaption>{e(b[1].caption)}</figcaption></figure>")
        out.append("</body></html>")
        return "\n".join(out)

    def write(self, directory, stem: str = "report") -> dict[str, Path]:
        """Write ``stem.md``, ``stem.html`` and every figure's PNG into ``directory``."""
        d = Path(directory)
        paths = {}
        for b in self.blocks:
            if b[0] == "fig":
                paths[b[1].name] = atomic_write_bytes(d / f"{b[1].name}.png", b[1].png)
        paths["md"] = atomic_write_text(d / f"{stem}.md", self.markdown())
        paths["html"] = atomic_write_text(d / f"{stem}.html", self.html())
        return paths
