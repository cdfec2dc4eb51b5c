"""Building blocks for human reports: one document rendered as Markdown and self-contained HTML.

A :class:`Document` collects headings, paragraphs, tables and matplotlib figures; ``write(dir,
stem)`` saves each figure as PNG, the Markdown (figures linked, all text escaped) and the HTML
(figures embedded as base64, so the file opens anywhere) as one report set
(:func:`write_report_set`): a folder never mixes the files of two runs. Rendering is pure: no
printing.
"""
from __future__ import annotations

import base64
import errno
import html
import io
import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

import numpy as np

from droneid.errors import ConfigError
from droneid.core.io_util import atomic_write_bytes, atomic_write_text, current_umask, json_text
from droneid.core.numerics import to_float

__all__ = ["Document", "new_figure", "png_bytes", "fmt", "efmt", "text_table", "md_escape",
           "write_report_set", "break_gaps"]

#: verdict box colours: (background, border) per verdict colour
_VERDICT_CSS = {"green": ("#eef5ee", "#2a7"), "grey": ("#f2f2f2", "#888"), "red": ("#fbeaea", "#c33"),
                "amber": ("#fff4dd", "#e90")}


#: characters that Markdown may read as syntax anywhere in a line
_MD_INLINE = re.compile(r"([\\`*\[\]|!])|(?<![A-Za-z0-9])_|_(?![A-Za-z0-9])")
#: an ``&`` that would start an HTML entity, a ``<`` that would open a tag or comment
_MD_ENTITY = re.compile(r"&(?=#?[A-Za-z0-9]+;)")
_MD_TAG = re.compile(r"<(?=[A-Za-z/!?])")
#: characters that start a heading, quote, list or rule at the beginning of a line
_MD_LINE_START = re.compile(r"^(\s*)([#>+=*-]+|\d+[.)])(?=\s|$)", re.MULTILINE)


def md_escape(text, line_start: bool = True) -> str:
    """``text`` as literal Markdown text: a ``<`` that could open an HTML tag (before a letter,
    ``/``, ``!`` or ``?``) and an ``&`` that could start an entity become entities, so no markup
    gets through while "RMSE 1.5 -> 1.4" and "(< 1 %)" stay readable as they are; Markdown's
    punctuation (`` ` * [ ] | ! \\ `` and word-edge ``_``) is backslash-escaped, and a line
    starting like a heading, quote or list is escaped at its start (unless ``line_start`` is
    false: table cells). Intra-word underscores (``vx_dot``) stay readable."""
    s = _MD_ENTITY.sub("&amp;", str(text))
    s = _MD_TAG.sub("&lt;", s)
    s = _MD_INLINE.sub(lambda m: "\\" + m.group(0), s)
    if not line_start:
        return s
    return _MD_LINE_START.sub(lambda m: m.group(1) + m.group(2)[:-1] + "\\" + m.group(2)[-1]
                              if m.group(2)[0].isdigit() else m.group(1) + "\\" + m.group(2), s)


def new_figure(width_in: float = 7.0, height_in: float = 3.6):
    """A matplotlib figure on the non-interactive Agg canvas (no display needed)."""
    from matplotlib.figure import Figure
    return Figure(figsize=(width_in, height_in), dpi=110, layout="constrained")


def break_gaps(x, ys, t=None, flight=None, factor: float = 5.0):
    """``(x, [y, ...])`` with NaN inserted wherever the samples are not contiguous, so a plotted
    line is broken there instead of bridging the gap.

    A gap is where ``flight`` (one id per sample) changes, or where the time step of ``t`` (s;
    defaults to ``x``) is non-positive or more than ``factor`` times the median positive step
    (e.g. the seconds the vehicle sat on the ground, which the dataset dropped). Returns float
    arrays one NaN longer per gap.
    """
    x = np.asarray(x, float)
    ys = [np.asarray(y, float) for y in ys]
    tt = x if t is None else np.asarray(t, float)
    if tt.size < 2:
        return x, ys
    dt = np.diff(tt)
    pos = dt[dt > 0]
    med = float(np.median(pos)) if pos.size else 0.0
    brk = (dt <= 0) | (dt > factor * med) if med > 0 else np.zeros(dt.size, bool)
    if flight is not None and len(flight) == tt.size:
        fl = np.asarray(flight)
        brk |= fl[1:] != fl[:-1]
    idx = np.flatnonzero(brk) + 1
    if not idx.size:
        return x, ys
    return np.insert(x, idx, np.nan), [np.insert(y, idx, np.nan) for y in ys]


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


def efmt(v) -> str:
    """An error value, 4 significant figures; float round-off (< 1e-12) shown as 0."""
    x = to_float(v)
    return "0" if math.isfinite(x) and abs(x) < 1e-12 else fmt(v)


def text_table(header, rows) -> str:
    """A plain-text table: first column left-aligned, the others right-aligned, a dashed rule."""
    cols = list(zip(*([header] + rows)))
    widths = [max(len(str(c)) for c in col) for col in cols]
    line = lambda r: "  ".join(str(c).ljust(w) if i == 0 else str(c).rjust(w)  # noqa: E731
                               for i, (c, w) in enumerate(zip(r, widths)))
    return "\n".join([line(header), "  ".join("-" * w for w in widths)] + [line(r) for r in rows])


def png_bytes(fig) -> bytes:
    """The matplotlib figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


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

    def verdict(self, text: str, colour: str = "grey") -> "Document":
        """A prominent one-sentence conclusion (bold, in a box in HTML, coloured by what it says:
        ``green`` better, ``grey`` no better or no verdict, ``red`` worse, ``amber`` not to be
        trusted)."""
        self.blocks.append(("verdict", text, colour if colour in _VERDICT_CSS else "grey"))
        return self

    def side_by_side(self, *items) -> "Document":
        """Figures shown beside each other (wrapping on narrow pages); each item is
        ``(fig_or_png_bytes, name, caption)``; ``name`` becomes ``name.png``."""
        self.blocks.append(("row", [_Figure(n, f if isinstance(f, (bytes, bytearray)) else png_bytes(f), c)
                                    for f, n, c in items]))
        return self

    def notes(self, items: Sequence[str], summary: str = "") -> "Document":
        """Notes that qualify the results, folded under one line (``summary``; default "N
        notes") so that they never push a verdict below the first screen: a ``<details>`` in
        HTML, a list under a bold line in Markdown. No block without ``items``."""
        items = [str(i) for i in items]
        if items:
            self.blocks.append(("notes", summary or f"{len(items)} note{'s' * (len(items) > 1)}", items))
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
        self.blocks.append(("fig", _Figure(name, png_bytes(fig), caption)))
        return self

    def _figs(self):
        for b in self.blocks:
            if b[0] == "fig":
                yield b[1]
            elif b[0] == "row":
                yield from b[1]

    # -- rendering ----------------------------------------------------------------------------
    def markdown(self) -> str:
        """The document as Markdown; all text is escaped (:func:`md_escape`), so a file name
        such as ``<img src=x onerror=alert(1)>.csv`` shows as text, never as HTML or a link."""
        esc = md_escape
        out = [f"# {esc(self.title)}", ""]
        for b in self.blocks:
            if b[0] == "h":
                out += ["#" * b[1] + " " + esc(b[2]), ""]
            elif b[0] == "p":
                out += [esc(b[1]), ""]
            elif b[0] == "verdict":
                mark = {"green": "✅", "amber": "⚠️", "red": "❌"}.get(b[2], "➖")
                out += [f"{mark} **{esc(b[1])}**", ""]
            elif b[0] == "row":
                for f in b[1]:
                    out += [f"![{esc(f.caption or f.name)}]({quote(f.name)}.png)", ""]
                    if f.caption:
                        out += [f"*{esc(f.caption)}*", ""]
            elif b[0] == "notes":
                out += [f"**{esc(b[1])}**", ""] + [f"- {esc(n, line_start=False)}" for n in b[2]] + [""]
            elif b[0] == "code":
                fence = "`" * max(3, 1 + max((len(r) for r in re.findall(r"`+", b[1])), default=0))
                out += [fence, b[1], fence, ""]
            elif b[0] == "table":
                cell = lambda c: md_escape(" ".join(c.split("\n")), line_start=False)  # noqa: E731
                out.append("| " + " | ".join(cell(h) for h in b[1]) + " |")
                out.append("|" + "---|" * len(b[1]))
                out += ["| " + " | ".join(cell(c) for c in r) + " |" for r in b[2]]
                out.append("")
            elif b[0] == "fig":
                out += [f"![{esc(b[1].caption or b[1].name)}]({quote(b[1].name)}.png)", ""]
                if b[1].caption:
                    out += [f"*{esc(b[1].caption)}*", ""]
        return "\n".join(out)

    def html(self) -> str:
        e = html.escape
        out = ["<!DOCTYPE html>", "<html><head><meta charset='utf-8'>", f"<title>{e(self.title)}</title>",
               "<style>body{font-family:sans-serif;max-width:70em;margin:2em auto;padding:0 1em;"
               "overflow-wrap:anywhere}"
               ".tbl{overflow-x:auto;max-width:100%}"
               "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:.25em .6em;"
               "text-align:right;white-space:nowrap;overflow-wrap:normal}th{background:#eee}"
               "td:first-child,th:first-child{text-align:left;white-space:normal;overflow-wrap:anywhere}"
               "details.notes{margin:.6em 0;color:#444}details.notes summary{cursor:pointer}"
               "pre{background:#f6f6f6;padding:.6em;white-space:pre-wrap;overflow-wrap:anywhere;"
               "max-width:100%;box-sizing:border-box}"
               "img{max-width:100%;height:auto}figure{margin:1em 0;min-width:0}"
               ".row{display:flex;flex-wrap:wrap;gap:1em;align-items:flex-start}"
               ".row figure{flex:1 1 26em;max-width:100%}"
               ".verdict{font-size:120%;font-weight:bold;padding:.5em .8em;border-left:.3em solid}"
               + "".join(f".verdict.{k}{{background:{bg};border-left-color:{fg}}}" for k, (bg, fg) in _VERDICT_CSS.items()) +
               "figcaption{color:#555;font-size:90%}</style></head><body>", f"<h1>{e(self.title)}</h1>"]
        img = lambda f: (f"<figure><img alt='{e(f.name)}' src='data:image/png;base64,"  # noqa: E731
                         f"{base64.b64encode(f.png).decode('ascii')}'><figcaption>{e(f.caption)}</figcaption></figure>")
        for b in self.blocks:
            if b[0] == "h":
                out.append(f"<h{b[1]}>{e(b[2])}</h{b[1]}>")
            elif b[0] == "p":
                out.append(f"<p>{e(b[1])}</p>")
            elif b[0] == "verdict":
                out.append(f"<p class='verdict {b[2]}'>{e(b[1])}</p>")
            elif b[0] == "row":
                out.append("<div class='row'>" + "".join(img(f) for f in b[1]) + "</div>")
            elif b[0] == "notes":
                out.append(f"<details class='notes'><summary>{e(b[1])}</summary>"
                           + "".join(f"<p>{e(n)}</p>" for n in b[2]) + "</details>")
            elif b[0] == "code":
                out.append(f"<pre>{e(b[1])}</pre>")
            elif b[0] == "table":
                out.append("<div class='tbl'><table><tr>" + "".join(f"<th>{e(h)}</th>" for h in b[1]) + "</tr>")
                out += ["<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in b[2]]
                out.append("</table></div>")
            elif b[0] == "fig":
                out.append(img(b[1]))
        out.append("</body></html>")
        return "\n".join(out)

    def files(self, stem: str = "report") -> dict[str, bytes | str]:
        """{file name: content}: ``stem.md``, ``stem.html`` and every figure's PNG."""
        out: dict[str, bytes | str] = {f"{f.name}.png": f.png for f in self._figs()}
        out[f"{stem}.md"] = self.markdown()
        out[f"{stem}.html"] = self.html()
        return out

    def write(self, directory, stem: str = "report", data: Mapping[str, object] | None = None
              ) -> dict[str, Path]:
        """Write ``stem.md``, ``stem.html``, every figure's PNG and the ``data`` files (JSON file
        name -> object, e.g. ``{"result.json": result}``) into ``directory`` as one report set
        (:func:`write_report_set`: the folder never mixes two runs' files).

        Returns paths by key: ``md``, ``html``, each figure's name, each data file's name, and
        ``json`` when ``data`` holds exactly one file.
        """
        data = dict(data or {})
        files = {name: json_text(obj) for name, obj in data.items()}
        files.update(self.files(stem))
        written = write_report_set(directory, files)
        paths = {f.name: written[f"{f.name}.png"] for f in self._figs()}
        paths.update({name: written[name] for name in data})
        if len(data) == 1:
            paths["json"] = written[next(iter(data))]
        paths["md"] = written[f"{stem}.md"]
        paths["html"] = written[f"{stem}.html"]
        return paths


#: the hidden file listing the files of the report set a folder holds
MANIFEST = ".droneid-report.json"
#: the visible marker present while a report set is written in place
INCOMPLETE = "REPORT_INCOMPLETE.txt"


def write_report_set(directory, files: Mapping[str, bytes | str]) -> dict[str, Path]:
    """Write ``files`` ({plain file name: bytes or text}) into ``directory`` as one run's set.

    The folder holds one run's files at any moment, even when the process is killed:

    - when ``directory`` does not exist, or holds only the files of an earlier report set (as
      listed in its manifest ``.droneid-report.json``), the new set is written into a fresh
      sibling folder, which then replaces ``directory`` by rename; the earlier set is deleted;
    - when it holds other files too (e.g. the user's logs), the set is written in place: a
      visible ``REPORT_INCOMPLETE.txt`` marker is written first and the earlier set's files (and
      any file the new set replaces) are deleted, then every file is written atomically, then
      the manifest, and the marker is removed last. A killed run leaves the marker beside an
      incomplete set of the new run, never a file of the earlier run.

    Between the two renames of a swap the folder is briefly absent; a run killed exactly there
    leaves the new set in a hidden ``.NAME.*.new`` sibling. The user's other files are never
    moved or deleted.

    Returns {file name: path}. Raises :class:`ConfigError` for a name that is not a plain
    file name, and the ``OSError`` of a folder that cannot be written (naming the folder).
    """
    d = Path(directory)
    for name in files:
        if not name or name in (".", "..", MANIFEST, INCOMPLETE) or "/" in name or "\\" in name \
                or "\0" in name:
            raise ConfigError(f"report file name {name!r} is not a plain file name")
    blobs = {n: c.encode("utf-8") if isinstance(c, str) else bytes(c) for n, c in files.items()}
    if d.exists() and not d.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "exists and is not a folder", str(d))
    previous = _manifest_files(d)
    if not d.is_symlink() and (not d.exists() or _only(d, previous)):
        try:
            return _swap_in(d, blobs)
        except OSError as exc:
            if exc.errno not in (errno.EXDEV, errno.EBUSY, errno.EPERM, errno.EACCES):
                raise
            # a mount point or a folder we may fill but not rename: fall back to in place
    return _write_in_place(d, blobs, previous)


def _manifest_files(d: Path) -> set[str]:
    try:
        listed = json.loads((d / MANIFEST).read_text(encoding="utf-8")).get("files", [])
    except (OSError, ValueError, AttributeError):
        return set()
    return {n for n in listed if isinstance(n, str) and n and "/" not in n and n not in (".", "..")}


def _only(d: Path, names: set[str]) -> bool:
    """True when every entry of ``d`` is a file of the earlier set (or its bookkeeping)."""
    allowed = names | {MANIFEST, INCOMPLETE}
    return all(e.name in allowed and e.is_file() and not e.is_symlink() for e in d.iterdir())


def _manifest(names) -> bytes:
    return (json.dumps({"writer": "droneid", "files": sorted(names)}, indent=1) + "\n").encode()


def _swap_in(d: Path, blobs: dict[str, bytes]) -> dict[str, Path]:
    d.parent.mkdir(parents=True, exist_ok=True)
    new = Path(tempfile.mkdtemp(prefix=f".{d.name}.", suffix=".new", dir=d.parent))
    old = None
    try:
        os.chmod(new, 0o777 & ~current_umask())
        for name, blob in blobs.items():
            atomic_write_bytes(new / name, blob)
        atomic_write_bytes(new / MANIFEST, _manifest(blobs))
        if d.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{d.name}.", suffix=".old", dir=d.parent))
            os.rename(d, old / d.name)
        os.rename(new, d)
    except BaseException:
        if old is not None and not d.exists() and (old / d.name).exists():
            os.rename(old / d.name, d)  # put the earlier set back
        shutil.rmtree(new, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return {name: d / name for name in blobs}


def _write_in_place(d: Path, blobs: dict[str, bytes], previous: set[str]) -> dict[str, Path]:
    atomic_write_text(d / INCOMPLETE, "droneid is writing a report here. If this file stays, the run "
                                      "was stopped and the report files beside it are incomplete.\n")
    (d / MANIFEST).unlink(missing_ok=True)
    for name in previous | set(blobs):  # files of the earlier set, and those the new one replaces
        if (d / name).is_file() and not (d / name).is_symlink():
            (d / name).unlink()
    paths = {name: atomic_write_bytes(d / name, blob) for name, blob in blobs.items()}
    atomic_write_bytes(d / MANIFEST, _manifest(blobs))
    (d / INCOMPLETE).unlink()
    return paths
