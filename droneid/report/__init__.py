"""Reports for people, one package: :mod:`.document` (the Markdown/HTML :class:`Document`, number
formats, text tables, the atomic report-set writer) and one renderer per result kind,
:mod:`.identify`, :mod:`.diagnose` and :mod:`.study`. Each renderer takes the result as plain data
(what its JSON file holds) and offers the same three verbs: ``text(result) -> str`` for the
terminal, ``document(result) -> Document`` and ``write(result, directory) -> {name: Path}``.
Nothing here recomputes from logs, so a saved result can be re-rendered anywhere.
"""
from .document import Document, efmt, fmt, text_table, write_report_set

__all__ = ["Document", "efmt", "fmt", "text_table", "write_report_set"]
