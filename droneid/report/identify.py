"""Rendering an identification result: terminal text, report.md/report.html with PNG figures.

Every function here takes the typed result (:class:`droneid.identify.result.IdentificationResult`; a
``result.json`` dict is read with ``from_dict`` first, which refuses another schema) and renders
it from its attributes; nothing is recomputed from logs, so a saved result can be re-rendered
anywhere.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import sympy as sp

from droneid.fitting.constancy import constancy_line
from droneid.errors import ConfigError
from droneid.core.expressions import parse_expression
from droneid.identify.pipeline import IdentificationResult, TargetResult
from droneid.report.rollout import ONE_STEP_POSITION, horizon_figures
from droneid.report.rotation import rotation_lines, rotation_section
from droneid.core.numerics import to_float
from droneid.core.regression import LOSS
from droneid.report.document import Document, break_gaps, efmt, fmt, new_figure, text_table
from droneid.core.text import round_floats
from droneid.fitting.verdict import VERDICT_KINDS

__all__ = ["text", "document", "write", "pareto_front", "compact", "as_result"]

LADDER_HEADER = ("model", "e_d train", "e_d validation", "e_d test", "e_c test")


def as_result(result) -> IdentificationResult:
    """The typed result: ``result`` itself, or a result.json dict read back (DataError in one
    line for another schema)."""
    return result if isinstance(result, IdentificationResult) else IdentificationResult.from_dict(result)


def ladder_rows(tr: TargetResult) -> list[list[str]]:
    """The ladder of one target: empirical as given -> refit -> + delay -> + effects -> final."""
    return [[("FINAL: " if r.name == "final" else "") + r.description, efmt(r.rmse_train),
             efmt(r.rmse_validation), efmt(r.rmse_test), efmt(r.constraint_rmse_test)]
            for r in tr.ladder]


def method_line(result: IdentificationResult) -> str:
    """How the errors were measured (printed with every error table)."""
    cfg = result.config
    return (f"errors in m/s² (RMSE); targets by {cfg.method} differences at Ts = {cfg.ts} s; "
            f"fits and validation: {LOSS} refit of the same terms, {result.plan.validation or 'blocked CV'} "
            f"(training flights only); e_c = constraint RMSE")


def interval_lines(tr: TargetResult) -> list[str]:
    """The final model's coefficients with their 95 % intervals, one line."""
    final = tr.final_rung
    if not final.intervals:
        return []
    parts = []
    for lab, iv in final.intervals.items():
        c = final.intercept if lab == "intercept" else final.terms[lab]
        if lab in final.held:
            parts.append(f"{lab} {efmt(c)} [{efmt(iv.low)}, {efmt(iv.high)}] held")
        elif iv.low == iv.high == c and lab != "intercept":   # fixed by the prior or the effect's own test
            parts.append(f"{lab} {efmt(c)} fixed")
        else:
            parts.append(f"{lab} {efmt(c)} [{efmt(iv.low)}, {efmt(iv.high)}]")
    several = any(c.unit == "flight" for c in final.constancy.values())
    how = ("block bootstrap over the training flights' (flight, time block) units; a vehicle "
           "constant's widened to cover how the flights differ" if several else
           "block bootstrap over the training flights' (flight, time block) units")
    return [f"  95 % intervals ({how}): " + "; ".join(parts),
            *filter(None, [constancy_line(final.constancy)])]


def screened_lines(tr: TargetResult) -> list[str]:
    """Implausible samples screened out of the training and test data (count per signal)."""
    out = []
    for where, counts in tr.screened.items():
        if counts:
            out.append(f"SCREENED ({where}): " + ", ".join(f"{n} {c}" for n, c in counts.items())
                       + " implausible sample(s) or jump(s); the rows that use them are left out")
    return out


_NAME = re.compile(r"[A-Za-z_]\w*")


def readable_expr(text: str, sig: int = 4) -> str:
    """A prior feature's expression as a person reads it: a common numeric factor pulled out
    (``2.55e-10*rpm1**2 + 2.55e-10*rpm2**2`` -> ``2.55e-10*(rpm1**2 + rpm2**2)``) and floats to
    ``sig`` significant figures. Display only: result.json keeps the full expression. Parsed
    with the project's safe parser (a saved result may come from anywhere); text it refuses is
    shown with its floats rounded only."""
    try:
        expr = sp.factor_terms(parse_expression(str(text), _NAME.findall(str(text))))
        text = str(expr)
    except ConfigError:
        pass
    return round_floats(text, sig)


def _legend(tr: TargetResult) -> list[str]:
    return [f"  ⟨{p.name}⟩ = {readable_expr(p.expr)}" + (f"   ({p.description})" if p.description else "")
            for p in tr.prior_features]


def _constraints_label(result: IdentificationResult) -> str:
    """The constraint sets the runs trained on, as the targets record them (``paper`` means the
    prior's own set: the record names it)."""
    used = sorted({tr.constraints for tr in result.targets.values()})
    own = " (the prior's own, docs/priors.md)" if result.config.constraints == "paper" else ""
    return ", ".join(used) + (own if any(u != "none" for u in used) else "") if used else str(result.config.constraints)


def _guard_line(tr: TargetResult) -> str:
    g = tr.guards
    return (f"SNGP runs: {len(tr.runs)}; rejected as implausible: {g.implausible}; "
            f"no evolved term left after the guards: {g.no_evolved_term_left}; "
            f"rejected for breaking the constraints: {g.constraints_broken}; "
            f"drag not growing with speed: {g.drag_not_monotone}")


def _delay_text(tr: TargetResult) -> str:
    return ", ".join(f"{k}(t {'−' if v > 0 else '+'} {1000 * abs(v):.0f} ms)" for k, v in tr.final.delays_s.items())


def text(result) -> str:
    """The terminal summary: per target the verdict, the equation, the ladder and the notes."""
    result = as_result(result)
    cfg, plan = result.config, result.plan
    out = [f"droneid identify: prior {plan.prior_used or cfg.prior} with {cfg.prior_features} prior "
           f"feature(s), constraints {_constraints_label(result)}, {cfg.runs} run(s) of "
           f"{cfg.generations} generations x population {cfg.population_size}"
           + (" (quick budget)" if cfg.quick else "")]
    out += [f"NOTE: {note}" for note in result.notes]
    for name, tr in result.targets.items():
        out += ["", f"== {name}  ({tr.n_train} training / {tr.n_test} test samples; {tr.test_data})",
                tr.verdict, tr.equation, *_legend(tr), *interval_lines(tr),
                f"  expanded: {name} = {tr.final.text()}"]
        if tr.final.delays_s:
            out.append("  offset inputs: " + _delay_text(tr))
        out += ["", text_table(list(LADDER_HEADER), ladder_rows(tr)), method_line(result), _guard_line(tr)]
        out += screened_lines(tr)
        out += [f"NOTE: {note}" for note in tr.notes if note != tr.test_data]
    out += horizon_lines(result.horizons)
    out += rotation_lines(result.rotation)
    return "\n".join(out)


def horizon_rows(h: dict) -> tuple[list, list]:
    """(header, rows) of the multi-step table: velocity RMSE (m/s) per model and horizon
    (``h``: the result's ``horizons``, :func:`droneid.simulation.rollout.horizon_section`)."""
    if "rmse" not in h or not h["rmse"]:
        return [], []
    axes = [a for a in ("vx", "vy", "vz", "position")
            if any(a in e for per in h["rmse"].values() for e in per.values())]
    header = ["model", "horizon"] + [f"{a} ({'m' if a == 'position' else 'm/s'})" for a in axes]
    rows = []
    for m, per in h["rmse"].items():
        for step, sec in zip(h["steps"], h["seconds"]):
            e = per[str(step)] if str(step) in per else {}
            rows.append([m, f"{step} ({sec:.3g} s)"] + [efmt(e[a]) if a in e else "—" for a in axes])
    return header, rows


def horizon_lines(h: dict) -> list[str]:
    header, rows = horizon_rows(h)
    if not rows:
        return []
    return ["", "== multi-step prediction on the test flights (velocity integrated from each sample, "
                "inputs from the log; RMSE against the logged velocity)", text_table(header, rows),
            f"steps of {h['dt_s']:.3g} s; starts per horizon: "
            + ", ".join(f"{k}: {v}" for k, v in h["n_starts"].items()), ONE_STEP_POSITION[0].upper() + ONE_STEP_POSITION[1:]]


# ------------------------------------------------------------------------------------------------
# figures


def pareto_front(points: np.ndarray) -> np.ndarray:
    """Mask of the non-dominated rows of ``points`` (n, 2), both objectives minimised."""
    pts = np.asarray(points, float)
    keep = np.ones(len(pts), bool)
    for i, p in enumerate(pts):
        if not np.all(np.isfinite(p)):
            keep[i] = False
            continue
        dom = np.all(pts <= p, axis=1) & np.any(pts < p, axis=1)
        keep[i] = not dom.any()
    return keep


def _x_axis(series: dict):
    t = np.asarray(series["t"], float)
    fl = np.asarray(series["flight"], int)
    if t.size and (fl.size == 0 or np.all(fl == fl[0])):
        return t, "time in test flight (s)"
    return np.arange(t.size), "test sample index (flights one after another; 1 sample = 1 Ts)"


def _gapped(s: dict, *ys):
    """x axis, its label and the ``ys`` with NaN at every gap in time or change of flight."""
    x, xl = _x_axis(s)
    t = s["t"] or None
    fl = s["flight"] or None
    xg, yg = break_gaps(x, ys, t=t if t is not None and len(t) == len(x) else None, flight=fl)
    return xg, xl, yg


def _tex_tokens(e) -> list[str]:
    """LaTeX of the sympy expression ``e`` as tokens whose concatenation is the whole; a line may
    break between any two tokens (between the terms of a sum, the factors of a product)."""
    import sympy
    if isinstance(e, sympy.Add):
        out = []
        for i, t in enumerate(sympy.Add.make_args(e)):
            neg = t.could_extract_minus_sign()
            out += ([" - " if i else "-"] if neg else ([" + "] if i else [])) + _tex_tokens(-t if neg else t)
        return out
    if isinstance(e, sympy.Mul) and len(sympy.latex(e)) > 30:
        out = []
        for f in e.as_ordered_factors():
            if out:
                out.append(r" \cdot ")
            out += ["("] + _tex_tokens(f) + [")"] if isinstance(f, sympy.Add) else _tex_tokens(f)
        return out
    return [sympy.latex(e)]


def _math_lines(lhs: str, expr, width: int = 110, signals=None) -> list[str] | None:
    """The equation ``lhs = expr`` as mathtext lines (sympy LaTeX, numbers to 4 significant
    figures), wrapped between terms and factors so that no line is much longer than ``width``
    LaTeX characters; None if ``expr`` does not parse."""
    import sympy
    try:  # the safe parser, never sympify: a saved result.json may come from anywhere
        e = parse_expression(expr, signals if signals is not None else _NAME.findall(expr),
                             what="final model") if isinstance(expr, str) else expr
        e = e.xreplace({n: sympy.Float(float(n), 4) for n in e.atoms(sympy.Float)})
        tokens = _tex_tokens(e)
    except (ConfigError, TypeError, ValueError, AttributeError):
        return None
    name = lhs.replace("_dot", "")
    head = r"\dot{%s}_{%s} = " % (name[0], name[1:]) if len(name) == 2 and name[0] == "v" else lhs + " = "
    lines, cur = [], head
    for tok in tokens:
        if len(cur) + len(tok) > width and cur not in (head, r"\quad "):
            lines.append(cur)
            cur = r"\quad "
        cur += tok
    lines.append(cur)
    return ["$" + ln.replace(r"\operatorname", r"\mathrm") + "$" for ln in lines]


def fig_equation(name: str, tr: TargetResult):
    """The final model typeset with matplotlib's mathtext (no LaTeX install, no network), wrapped
    over several lines, the figure as wide as its longest line; None when mathtext cannot render
    it."""
    lines = _math_lines(name, tr.final.expr)
    if not lines:
        return None
    step = 0.42  # inches per line
    fig = new_figure(7.5, step * len(lines) + 0.2)
    fig.set_layout_engine(None)
    texts = [fig.text(0.1 / 7.5, 1 - (0.1 + step * (i + 0.75)) / (step * len(lines) + 0.2), ln,
                      fontsize=12, va="baseline") for i, ln in enumerate(lines)]
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(fig)
    try:
        canvas.draw()
    except ValueError:  # mathtext could not parse a construct: the plain equation is shown anyway
        return None
    r = canvas.get_renderer()
    width_in = max(t.get_window_extent(r).x1 for t in texts) / fig.dpi + 0.1
    fig.set_size_inches(max(width_in, 2.0), step * len(lines) + 0.2)
    for t in texts:  # keep the left margin constant in inches
        t.set_x(0.1 / max(width_in, 2.0))
    return fig


def fig_measured_vs_predicted(name: str, tr: TargetResult):
    s = tr.test_series
    x, xl, (y, emp, ide) = _gapped(s, s["y"], s["empirical"], s["identified"])
    fig = new_figure(7.5, 3.4)
    ax = fig.add_subplot()
    ax.plot(x, y, color="k", lw=1.2, label="measured")
    ax.plot(x, emp, color="tab:orange", lw=1, label="empirical model")
    ax.plot(x, ide, color="tab:blue", lw=1, label="final model")
    ax.set_xlabel(xl)
    ax.set_ylabel(f"{name} (m/s²)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{name} on the test data")
    return fig


def fig_residuals(name: str, tr: TargetResult):
    s = tr.test_series
    y = np.asarray(s["y"], float)
    x, xl, (r_emp, r_ref, r_ide) = _gapped(s, y - np.asarray(s["empirical"], float),
                                           y - np.asarray(s["empirical_refit"], float),
                                           y - np.asarray(s["identified"], float))
    fig = new_figure(7.5, 3.0)
    ax = fig.add_subplot()
    ax.plot(x, r_emp, color="tab:orange", lw=0.9, label="empirical model")
    ax.plot(x, r_ref, color="tab:green", lw=0.9, alpha=0.7, label="prior refit")
    ax.plot(x, r_ide, color="tab:blue", lw=0.9, label="final model")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel(xl)
    ax.set_ylabel("measured − predicted (m/s²)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{name}: residual on the test data")
    return fig


def fig_runs(name: str, tr: TargetResult):
    e = np.sort(np.array([to_float(r.rmse_test) for r in tr.runs], float))
    fig = new_figure(6.0, 3.2)
    ax = fig.add_subplot()
    ax.plot(np.arange(1, e.size + 1), e, "o-", color="tab:blue", ms=4, label="identified runs")
    ax.axhline(to_float(tr.ladder[0].rmse_test), color="tab:orange", ls="--", label="empirical model")
    ax.axhline(to_float(tr.ladder[1].rmse_test), color="tab:green", ls=":", label="prior refit")
    ax.set_xlabel("run (sorted by test error)")
    from matplotlib.ticker import MaxNLocator
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("e_d test (m/s²)")
    if e.size and np.nanmax(e) > 0 and np.nanmax(e) / max(np.nanmin(e), 1e-12) > 30:
        ax.set_yscale("log")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{name}: runs sorted by test error")
    return fig


def fig_pareto(name: str, tr: TargetResult, gamma: float | None):
    pts = [(to_float(a["rmse_train"]), to_float(a["constraint_rmse_train"]))
           for r in tr.runs for a in r.archive]
    pts = np.array([p for p in pts if all(math.isfinite(v) for v in p)], float).reshape(-1, 2)
    if not len(pts):
        return None
    front = pareto_front(pts)
    fig = new_figure(6.0, 3.6)
    ax = fig.add_subplot()
    ax.scatter(pts[~front, 0], pts[~front, 1], s=8, color="0.7", label="archived models")
    order = np.argsort(pts[front, 0])
    ax.plot(pts[front, 0][order], pts[front, 1][order], "o-", color="tab:red", ms=4, label="Pareto front")
    if gamma:
        ax.axhline(gamma, color="k", ls="--", lw=0.8, label=f"γ = {gamma:g}")
    ax.set_xlabel("e_d train (m/s²)")
    ax.set_ylabel("e_c train (m/s²)")
    if np.all(pts[:, 1] > 0):
        ax.set_yscale("log")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{name}: Pareto front of the archives")
    return fig


# ------------------------------------------------------------------------------------------------
# documents


def document(result) -> Document:
    """report.md / report.html content: settings, per-target verdict, equation, ladder, figures."""
    result = as_result(result)
    cfg, plan = result.config, result.plan
    doc = Document("droneid identification report")
    delays = ", ".join(f"{k} {1000 * v:+.0f} ms" for k, v in plan.delays_s.items()) or "none"
    doc.paragraph(f"Prior '{plan.prior_used or cfg.prior}' with {cfg.prior_features} prior feature(s); "
                  f"constraints: {_constraints_label(result)}; input offsets: {delays}; {cfg.runs} SNGP run(s), "
                  f"{cfg.generations} generations, population {cfg.population_size}, "
                  f"seed {cfg.seed}; Ts {cfg.ts} s, {cfg.method} differences. "
                  f"Errors in m/s²: e_d is the RMSE on data, e_c the RMSE of constraint violations.")
    doc.heading("Verdicts")
    for name, tr in result.targets.items():
        doc.verdict(tr.verdict, VERDICT_KINDS[tr.verdict_kind] if tr.verdict_kind in VERDICT_KINDS else "grey")
    doc.notes([f"NOTE: {note}" for note in result.notes],
              f"{len(result.notes)} note(s) on the plan and the data (prior, offset, diagnosis, data fitness)")
    files = lambda part: ", ".join(str(f) for p in (result.provenance[part] if part in result.provenance else ()) for f in p["files"])  # noqa: E731
    doc.paragraph(f"Training logs: {files('train') or '—'}. Test logs: {files('test') or '—'}.")
    for name, tr in result.targets.items():
        doc.heading(name)
        doc.verdict(tr.verdict, VERDICT_KINDS[tr.verdict_kind] if tr.verdict_kind in VERDICT_KINDS else "grey")
        has_series = bool(tr.test_series["y"])
        eq = fig_equation(name, tr)
        top = []
        if eq is not None:
            top.append((eq, f"{name}_equation", "final model, in m/s²" + (
                "; delayed inputs: " + _delay_text(tr) if tr.final.delays_s else "")))
        if has_series:
            top.append((fig_measured_vs_predicted(name, tr), f"{name}_test_prediction",
                        "measured vs predicted on the test data (final model and empirical model)"))
        if top:
            doc.side_by_side(*top)
        doc.code("\n".join([tr.equation, *_legend(tr), *interval_lines(tr), *screened_lines(tr),
                            f"expanded: {name} = {tr.final.text()}"]))
        doc.table(LADDER_HEADER, ladder_rows(tr))
        doc.paragraph(method_line(result))
        doc.paragraph(f"{tr.n_train} training and {tr.n_test} test samples; {tr.test_data}. "
                      f"Inputs: {', '.join(tr.inputs)}. Constraints: {tr.constraints}.")
        own = [f"NOTE: {note}" for note in tr.notes if note != tr.test_data]
        doc.notes(own, f"{len(own)} note(s) on {name} (held coefficients, data range, rejected runs)")
        if tr.runs:
            chosen = tr.guards.chosen_run
            mark = " (its evolved terms are in the final model)"
            limit = tr.guards.constraint_limit
            doc.paragraph(_guard_line(tr) + " (errors of each run's own model on the rows it searched; "
                          f"'own e_c train < γ' says whether that model kept the constraints within γ = {cfg.gamma:g}. "
                          "The guards judge a run again once its evolved terms join the physical model"
                          + (f", against e_c ≤ {limit:.3g}" if limit is not None else "")
                          + ": a 'no' here is not a run rejected for breaking the constraints)")
            doc.table(["run", "seed", "e_d train", "e_d test", "e_c train", "e_c test", "own e_c train < γ", "wall (s)"],
                      [[str(i + 1) + (mark if i == chosen else ""), r.seed,
                        fmt(r.rmse_train), fmt(r.rmse_test), fmt(r.constraint_rmse_train),
                        fmt(r.constraint_rmse_test), "yes" if r.qualified else "no",
                        fmt(r.wall_s, 3)] for i, r in enumerate(tr.runs)])
        if has_series:
            doc.figure(fig_residuals(name, tr), f"{name}_residuals", "residual over time on the test data")
        if any(math.isfinite(to_float(r.rmse_test)) for r in tr.runs):
            doc.figure(fig_runs(name, tr), f"{name}_runs",
                       "runs sorted by test error; dashed: the empirical model's test error (cf. the paper's Figs. 2-3)")
        if tr.constraints != "none" and tr.runs:
            fig = fig_pareto(name, tr, cfg.gamma)
            if fig is not None:
                doc.figure(fig, f"{name}_pareto", "Pareto front of e_d^train vs e_c^train over the runs' archives")
    header, rows = horizon_rows(result.horizons)
    if rows:
        h = result.horizons
        doc.heading("Multi-step prediction on the test flights")
        doc.paragraph(f"From every test sample the model's velocity is integrated (RK4, steps of "
                      f"{h['dt_s']:.3g} s) with every other input read from the log; RMSE against the "
                      f"logged velocity per horizon (see docs/use-the-model.md for the exact metric); "
                      f"{ONE_STEP_POSITION}.")
        doc.table(header, rows)
        for name, png in horizon_figures(h).items():
            doc.png(png, name, "multi-step prediction: error against horizon" if "error" in name
                    else "predicted velocity traces over the measured one")
    rotation_section(doc, result.rotation)
    doc.paragraph("Versions: " + ", ".join(f"{k} {v}" for k, v in result.versions.items()))
    return doc


def write(result, directory) -> dict[str, Path]:
    """Write result.json, report.md, report.html and the PNGs into ``directory`` (atomically)."""
    result = as_result(result)
    return document(result).write(directory, "report", data={"result.json": result.to_dict()})


def compact(result) -> dict:
    """The result.json document without bulky parts (series, archives): for ``--json`` output."""
    out = as_result(result).to_dict()
    for tr in out["targets"].values():
        del tr["test_series"]
        for r in tr["runs"]:
            del r["archive"]
    return out
