"""Rendering a study result (:func:`droneid.identify.study.study`): the paper's Tables II-III as terminal
text, study.md/study.html with a box plot per target. Pure functions over the result.

Every function takes a :class:`~droneid.identify.study.StudyResult`, or the ``study.json`` document
(a dict), which is read through :meth:`StudyResult.from_dict` first, so a saved study renders
exactly like a fresh one. Errors are RMSEs in m/s².
"""
from __future__ import annotations

import math
from collections.abc import Mapping

from droneid.identify.study import PRIOR_VARIANTS, SCENARIOS, StudyResult, StudyTarget, prior_label
from droneid.report.document import Document, efmt, new_figure, text_table

__all__ = ["study_table", "text", "document", "write"]


def _result(result: StudyResult | Mapping) -> StudyResult:
    """The one input kind: a StudyResult as given, a study.json document read back."""
    return result if isinstance(result, StudyResult) else StudyResult.from_dict(result)


def _p(v) -> str:
    if v is None:
        return "—"
    v = float(v)
    if not math.isfinite(v):
        return "—"
    return f"{v:.2g}" if v >= 1e-3 else f"{v:.1e}"


def _direction(median, median_none, nprior: int) -> str:
    """' (lower)' / ' (higher)': the variant's median test error against no prior's (the
    rank-sum test is two-sided, so the p-value alone does not say which way)."""
    if nprior == 0 or median is None or median_none is None:
        return ""
    return " (lower)" if median < median_none else " (higher)" if median > median_none else ""


def study_table(result: StudyResult | Mapping) -> tuple[list[str], list[list[str]]]:
    """Header and rows shaped like the paper's Tables II-III: one row per scenario × prior
    variant, per target the median e_d^test, the median e_c^test and the two-sided rank-sum p-value of
    the test errors against the same scenario's no-prior variant, with the direction of the
    difference in medians."""
    result = _result(result)
    names = list(result.targets)
    header = ["scenario", "prior"]
    for t in names:
        header += [f"{t} e_d test", f"{t} e_c test", f"{t} p vs none"]
    rows = []
    for scenario, _ in SCENARIOS:
        for k in PRIOR_VARIANTS:
            row = [scenario, prior_label(k)]
            for t in names:
                tr = result.targets[t]
                v = tr.variant(scenario, k)
                none = tr.variant(scenario, 0).median_rmse_test
                row += [efmt(v.median_rmse_test), efmt(v.median_constraint_rmse_test),
                        _p(v.p_value_vs_no_prior) + _direction(v.median_rmse_test, none, k)]
            rows.append(row)
    for key, label in (("empirical", "as given"), ("empirical_refit", "refit (LS)")):
        row = ["empirical model", label]
        for t in names:
            e = getattr(result.targets[t], key)
            row += [efmt(e.get("rmse_test")), efmt(e.get("constraint_rmse_test")), "—"]
        rows.append(row)
    return header, rows


def text(result: StudyResult | Mapping) -> str:
    """The terminal report: budget, data per target, the table, the wall time."""
    result = _result(result)
    cfg = result.config
    head = (f"droneid study: {cfg['runs']} run(s) per variant, {cfg['generations']} generations x population "
            f"{cfg['population_size']}; medians over runs, errors in m/s²; p = Wilcoxon rank-sum test of the "
            f"test errors against the same scenario's no-prior variant.")
    lines = [head]
    for t, tr in result.targets.items():
        lines.append(f"{t}: {tr.n_train} training / {tr.n_test} test samples; {tr.test_data}")
        lines += [f"  NOTE: {n}" for n in tr.notes]
    if result.interrupted:
        lines.append(f"NOTE: interrupted; {result.runs_finished} of {result.runs_total} runs finished")
    header, rows = study_table(result)
    lines += ["", text_table(header, rows), "", f"wall time {result.wall_s:.1f} s ({result.backend})"]
    return "\n".join(lines)


def fig_study_box(t: str, tr: StudyTarget | Mapping):
    """Box plot of the test errors (m/s²) per scenario and prior variant of one target (a
    :class:`~droneid.identify.study.StudyTarget` or its ``study.json`` dict); the tick labels name the
    scenario and the prior variant in full."""
    if not isinstance(tr, StudyTarget):
        tr = StudyTarget.from_dict(tr)
    fig = new_figure(7.5, 3.8)
    ax = fig.add_subplot()
    data, labels = [], []
    for v in tr.variants.values():
        vals = [e for e in v.test_errors if e is not None and math.isfinite(e)]
        data.append(vals if vals else [float("nan")])
        labels.append(f"{v.scenario}\n{prior_label(v.prior_features)}")
    ax.boxplot(data, tick_labels=labels)
    ax.tick_params(axis="x", labelsize=8)
    ax.set_xlabel("scenario and prior variant")
    emp = tr.empirical.get("rmse_test")
    if emp is not None and math.isfinite(emp):
        ax.axhline(emp, color="tab:orange", ls="--", label="empirical model")
    ax.set_ylabel("e_d test (m/s²)")
    finite = [x for d in data for x in d if x == x]
    if finite and max(finite) / max(min(finite), 1e-12) > 30:
        ax.set_yscale("log")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    ax.set_title(f"{t}: test error per variant")
    return fig


def document(result: StudyResult | Mapping) -> Document:
    """study.md / study.html: the budget, the table and a box plot per target."""
    result = _result(result)
    cfg = result.config
    doc = Document("droneid study: prior features and constraints")
    doc.paragraph(f"{cfg['runs']} SNGP run(s) per (target, scenario, prior variant), {cfg['generations']} "
                  f"generations, population {cfg['population_size']}, seed {cfg['seed']}; prior '{cfg['prior']}', "
                  f"constraints '{cfg['constraints']}' in the constrained scenario. Medians over runs; errors "
                  f"in m/s²; p = Wilcoxon rank-sum test (scipy.stats.ranksums) of each prior variant's test "
                  f"errors against the no-prior variant of the same scenario.")
    if result.interrupted:
        doc.paragraph(f"NOTE: interrupted; {result.runs_finished} of {result.runs_total} runs finished.")
    header, rows = study_table(result)
    doc.table(header, rows)
    for t, tr in result.targets.items():
        doc.heading(t)
        doc.paragraph(f"{tr.n_train} training / {tr.n_test} test samples; {tr.test_data}.")
        for n in tr.notes:
            doc.paragraph(f"NOTE: {n}")
        fig = fig_study_box(t, tr)
        doc.figure(fig, f"study_{t}", "test errors per scenario and prior variant")
    return doc


def write(result: StudyResult | Mapping, directory) -> dict:
    """Write study.md, study.html, study.json (``result.to_dict()``) and the figures atomically
    into ``directory``; returns the written paths by name (see :meth:`Document.write`)."""
    result = _result(result)
    return document(result).write(directory, "study", data={"study.json": result.to_dict()})
