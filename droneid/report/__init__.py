"""Reports for people, one package: :mod:`.document` (the Markdown/HTML :class:`Document`, number
formats, text tables, the atomic report-set writer) and one renderer per result kind,
:mod:`.identify`, :mod:`.diagnose` and :mod:`.study`, each with the same three verbs:
``text(result) -> str`` for the terminal, ``document(result) -> Document`` and
``write(result, directory) -> {name: Path}``. :mod:`.predict` has ``text`` only (predict writes
no report set) and :mod:`.rollout` draws the multi-step prediction figures that identify's
report and ``predict --plot`` use. The identify renderer takes the result's JSON
document (``to_dict()``); study and diagnose take their result object or its JSON document
(read back through ``from_dict``), so a saved result can be re-rendered anywhere (a saved
diagnosis without the time-series figures: ``diagnosis.json`` does not hold the series).
Nothing here recomputes from logs.
"""
from droneid.report.document import Document, efmt, fmt, text_table, write_report_set

__all__ = ["Document", "efmt", "fmt", "text_table", "write_report_set"]
