"""Rendering an identification result: terminal text, report.md/report.html with PNG figures.

Every function here takes the result as plain data (the ``result.json`` dict, see
:meth:`droneid.identify.IdentificationResult.to_dict`) and renders it; nothing is recomputed
from logs, so a saved result can be re-rendered anywhere.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import sympy as sp

from ..errors import ConfigError
from ..expressions import parse_expression
from ..identify import VERDICT_KINDS, round_floats
from .rollout import horizon_figures
from ..numerics import to_float
from ..regression import LOSS
from .document import Document, break_gaps, efmt, fmt, new_figure, text_table

__all__ = ["error_rows", "text", "document", "write", "pareto_front", "compact",
           "ERROR_HEADER"]

ERROR_HEADER = ("model", "e_d train", "e_d test", "e_c test")


LADDER_HEADER = ("model", "e_d train", "e_d validation", "e_d test", "e_c test")


def ladder_rows(tr: dict) -> list[list[str]]:
    """The ladder of one target: empirical as given -> refit -> + delay -> + effects -> final."""
    return [[("FINAL: " if r["name"] == "final" else "") + r["description"], efmt(r.get("rmse_train")),
             efmt(r.get("rmse_validation")), efmt(r.get("rmse_test")), efmt(r.get("constraint_rmse_test"))]
            for r in tr.get("ladder") or []]


def method_line(cfg: dict) -> str:
    """How the errors were measured (printed with every error table)."""
    return (f"errors in m/s² (RMSE); targets by {cfg.get('method')} differences at Ts = {cfg.get('ts')} s; "
            f"fits and validation: {LOSS} refit of the same terms, {cfg.get('validation') or 'blocked CV'} "
            f"(training flights only); e_c = constraint RMSE")


def error_rows(tr: dict) -> list[list[str]]:
    """The comparison table of one target: empirical, refit, identified best and median."""
    def row(label, d):
        d = d or {}
        return [label, efmt(d.get("rmse_train")), efmt(d.get("rmse_test")), efmt(d.get("constraint_rmse_test"))]
    n = len(tr.get("runs") or [])
    return [row("empirical model as given", tr.get("empirical")),
            row("empirical model refit (LS)", tr.get("empirical_refit")),
            row("identified, best run", tr.get("identified")),
            row(f"identified, median of {n} runs", tr.get("identified_median"))]


def interval_lines(tr: dict) -> list[str]:
    """The final model's coefficients with their 95 % intervals, one line."""
    final = next((r for r in tr.get("ladder") or [] if r.get("name") == "final"), None)
    if not final or not final.get("intervals"):
        return []
    parts = []
    for lab, (a, b) in final["intervals"].items():
        c = final["intercept"] if lab == "intercept" else (final.get("terms") or {}).get(lab)
        held = " held" if lab in (final.get("held") or {}) else ""
        parts.append(f"{lab} {efmt(c)} [{efmt(a)}, {efmt(b)}]{held}")
    return ["  95 % intervals (block bootstrap over the training flights' time blocks): " + "; ".join(parts)]


def screened_lines(tr: dict) -> list[str]:
    """Implausible samples screened out of the training and test data (count per signal)."""
    out = []
    for where, counts in (tr.get("screened") or {}).items():
        if counts:
            out.append(f"SCREENED ({where}): " + ", ".join(f"{n} {c}" for n, c in counts.items())
                       + " implausible sample(s) or jump(s); the rows that use them are left out")
    return out


def _pct(v) -> str:
    v = to_float(v)
    return "—" if not math.isfinite(v) else f"{v:+.1f} %"


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


def _legend(tr: dict) -> list[str]:
    return [f"  ⟨{p['name']}⟩ = {readable_expr(p['expr'])}"
            + (f"   ({p['description']})" if p.get("description") else "")
            for p in tr.get("prior_features") or []]


def _constraints_label(cfg: dict) -> str:
    """``paper`` means the prior's own set: say which."""
    c = cfg.get("constraints")
    if c != "paper":
        return str(c)
    prior = cfg.get("prior_used") or cfg.get("prior")
    return "the paper's" if prior == "tilt-drag" else f"{prior}'s own (docs/priors.md)"


def text(result: dict) -> str:
    """The terminal summary: per target the equation, the error table and the improvement."""
    out = []
    cfg = result.get("config", {})
    out.append(f"droneid identify: prior {cfg.get('prior_used') or cfg.get('prior')} with {cfg.get('prior_features')} prior "
               f"feature(s), constraints {_constraints_label(cfg)}, {cfg.get('runs')} run(s) of "
               f"{cfg.get('generations')} generations x population {cfg.get('population_size')}"
               + (" (quick budget)" if cfg.get("quick") else ""))
    for note in result.get("notes") or []:
        out.append(f"NOTE: {note}")
    for name, tr in result["targets"].items():
        out += ["", f"== {name}  ({tr['n_train']} training / {tr['n_test']} test samples; {tr['test_data']})"]
        if tr.get("ladder"):
            out.append(tr.get("verdict") or "")
            out.append(tr.get("equation") or "")
            out += _legend(tr)
            out += interval_lines(tr)
            if tr.get("final"):
                out.append(f"  expanded: {tr['final']['equation']}")
                if tr["final"].get("delays_s"):
                    out.append("  offset inputs: " + ", ".join(f"{k}(t {'−' if v > 0 else '+'} {1000 * abs(v):.0f} ms)"
                                                               for k, v in tr["final"]["delays_s"].items()))
            out.append("")
            out.append(text_table(list(LADDER_HEADER), ladder_rows(tr)))
            out.append(method_line(cfg))
            g = tr.get("guards") or {}
            out.append(f"SNGP runs: {len(tr.get('runs') or [])}; rejected as implausible: {g.get('implausible', 0)}; "
                       f"no evolved term left after the guards: {g.get('no_evolved_term_left', 0)}; "
                       f"breaking the constraints: {g.get('constraints_broken', 0)}; "
                       f"drag not growing with speed: {g.get('drag_not_monotone', 0)}")
            out += screened_lines(tr)
            for note in tr.get("notes") or []:
                if note != tr["test_data"]:
                    out.append(f"NOTE: {note}")
            continue
        if tr.get("equation"):
            out.append(tr["equation"])
            out += _legend(tr)
            if tr.get("equation_expanded"):
                out.append(f"  expanded: {tr['equation_expanded']}")
        else:
            out.append("(no finished run)")
        out.append("")
        out.append(text_table(list(ERROR_HEADER), error_rows(tr)))
        imp = tr.get("improvement_pct") or {}
        out.append(f"errors in the target's units (m/s²); e_d = RMSE on data, e_c = constraint RMSE. "
                   f"Improvement of the best run's test error: {_pct(imp.get('vs_empirical'))} vs the "
                   f"empirical model, {_pct(imp.get('vs_empirical_refit'))} vs its refit.")
        for note in tr.get("notes") or []:
            if note != tr["test_data"]:
                out.append(f"NOTE: {note}")
    out += horizon_lines(result.get("horizons") or {})
    return "\n".join(out)


def horizon_rows(h: dict) -> tuple[list, list]:
    """(header, rows) of the multi-step table: velocity RMSE (m/s) per model and horizon."""
    if not h.get("rmse"):
        return [], []
    axes = [a for a in ("vx", "vy", "vz", "position")
            if any(a in e for per in h["rmse"].values() for e in per.values())]
    header = ["model", "horizon"] + [f"{a} ({'m' if a == 'position' else 'm/s'})" for a in axes]
    rows = []
    for m, per in h["rmse"].items():
        for step, sec in zip(h["steps"], h["seconds"]):
            e = per.get(str(step), {})
            rows.append([m, f"{step} ({sec:.3g} s)"] + [efmt(e.get(a)) if a in e else "—" for a in axes])
    return header, rows


def horizon_lines(h: dict) -> list[str]:
    header, rows = horizon_rows(h)
    if not rows:
        return []
    return ["", "== multi-step prediction on the test flights (velocity integrated from each sample, "
                "inputs from the log; RMSE against the logged velocity)", text_table(header, rows),
            f"steps of {h['dt_s']:.3g} s; starts per horizon: "
            + ", ".join(f"{k}: {v}" for k, v in (h.get("n_starts") or {}).items())]


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
    t = np.asarray(series.get("t") or [], float)
    fl = np.asarray(series.get("flight") or [], int)
    if t.size and (fl.size == 0 or np.all(fl == fl[0])):
        return t, "time in test flight (s)"
    return np.arange(t.size), "test sample index (flights one after another; 1 sample = 1 Ts)"


def _gapped(s: dict, *ys):
    """x axis, its label and the ``ys`` with NaN at every gap in time or change of flight."""
    x, xl = _x_axis(s)
    t = s.get("t") or None
    fl = s.get("flight") or None
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


def fig_equation(name: str, tr: dict):
    """The final model typeset with matplotlib's mathtext (no LaTeX install, no network), wrapped
    over several lines, the figure as wide as its longest line; None when there is no final
    expression or mathtext cannot render it."""
    fin = tr.get("final") or {}
    expr = fin.get("expr")
    lines = _math_lines(name, expr, signals=fin.get("signals")) if expr else None
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


def fig_measured_vs_predicted(name: str, tr: dict):
    s = tr["test_series"]
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


def fig_residuals(name: str, tr: dict):
    s = tr["test_series"]
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


def fig_runs(name: str, tr: dict):
    runs = tr.get("runs") or []
    e = np.sort(np.array([to_float(r.get("rmse_test")) for r in runs], float))
    fig = new_figure(6.0, 3.2)
    ax = fig.add_subplot()
    ax.plot(np.arange(1, e.size + 1), e, "o-", color="tab:blue", ms=4, label="identified runs")
    ax.axhline(to_float(tr["empirical"].get("rmse_test")), color="tab:orange", ls="--", label="empirical model")
    ax.axhline(to_float(tr["empirical_refit"].get("rmse_test")), color="tab:green", ls=":", label="prior refit")
    ax.set_xlabel("run (sorted by test error)")
    from matplotlib.ticker import MaxNLocator
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("e_d test (m/s²)")
    if e.size and np.nanmax(e) > 0 and np.nanmax(e) / max(np.nanmin(e), 1e-12) > 30:
        ax.set_yscale("log")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{name}: runs sorted by test error")
    return fig


def fig_pareto(name: str, tr: dict, gamma: float | None):
    pts = [(to_float(a.get("rmse_train")), to_float(a.get("constraint_rmse_train")))
           for r in tr.get("runs") or [] for a in (r.get("archive") or [])]
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


def document(result: dict) -> Document:
    """report.md / report.html content: config, per-target equation, table and figures."""
    cfg = result.get("config", {})
    doc = Document("droneid identification report")
    doc.paragraph(f"Prior '{cfg.get('prior')}' with {cfg.get('prior_features')} prior feature(s); "
                  f"constraints: {cfg.get('constraints')}; {cfg.get('runs')} SNGP run(s), "
                  f"{cfg.get('generations')} generations, population {cfg.get('population_size')}, "
                  f"seed {cfg.get('seed')}; Ts {cfg.get('ts')} s, {cfg.get('method')} differences. "
                  f"Errors in m/s²: e_d is the RMSE on data, e_c the RMSE of constraint violations.")
    for note in result.get("notes") or []:
        doc.paragraph(f"NOTE: {note}")
    prov = result.get("provenance") or {}
    files = lambda part: ", ".join(str(f) for p in prov.get(part) or [] for f in (p.get("files") or []))  # noqa: E731
    doc.paragraph(f"Training logs: {files('train') or '—'}. Test logs: {files('test') or '—'}.")
    for name, tr in result["targets"].items():
        doc.heading(name)
        if tr.get("verdict"):
            doc.verdict(tr["verdict"], VERDICT_KINDS.get(tr.get("verdict_kind") or "", "grey"))
        has_series = bool(tr.get("test_series", {}).get("y"))
        eq = fig_equation(name, tr)
        top = []
        if eq is not None:
            delays = (tr.get("final") or {}).get("delays_s") or {}
            top.append((eq, f"{name}_equation", "final model, in m/s²" + (
                "; delayed inputs: " + ", ".join(f"{k}(t − {1000 * v:.0f} ms)" for k, v in delays.items())
                if delays else "")))
        if has_series:
            top.append((fig_measured_vs_predicted(name, tr), f"{name}_test_prediction",
                        "measured vs predicted on the test data (final model and empirical model)"))
        if top:
            doc.side_by_side(*top)
        if tr.get("equation"):
            doc.code("\n".join([tr["equation"], *_legend(tr), *interval_lines(tr), *screened_lines(tr)]
                               + ([f"expanded: {tr['equation_expanded']}"] if tr.get("equation_expanded") else [])))
        if tr.get("ladder"):
            doc.table(LADDER_HEADER, ladder_rows(tr))
            doc.paragraph(method_line(cfg))
        doc.paragraph(f"{tr['n_train']} training and {tr['n_test']} test samples; {tr['test_data']}. "
                      f"Inputs: {', '.join(tr['inputs'])}.")
        if not tr.get("ladder"):  # a result of the first version (no ladder): its own table
            doc.table(ERROR_HEADER, error_rows(tr))
            imp = tr.get("improvement_pct") or {}
            doc.paragraph(f"Improvement of the best run's test error: {_pct(imp.get('vs_empirical'))} vs the "
                          f"empirical model, {_pct(imp.get('vs_empirical_refit'))} vs its least-squares refit. "
                          f"The best run is chosen by training error among runs meeting the constraint "
                          f"threshold, never by test error.")
            refit = tr["empirical_refit"].get("coefficients") or {}
            if refit:
                doc.paragraph("Empirical refit: " + ", ".join(f"{fmt(v)}·⟨{k}⟩" for k, v in refit.items())
                              + f" + {fmt(tr['empirical_refit'].get('intercept'))}")
        for note in tr.get("notes") or []:
            if note != tr["test_data"]:
                doc.paragraph(f"NOTE: {note}")
        if tr.get("runs"):
            chosen = (tr.get("guards") or {}).get("chosen_run") if tr.get("ladder") else tr.get("best_run")
            mark = " (its evolved terms are in the final model)" if tr.get("ladder") else " (best)"
            if tr.get("ladder"):
                g = tr.get("guards") or {}
                doc.paragraph(f"SNGP runs (errors of each run's own model on the rows it searched): "
                              f"{g.get('implausible', 0)} rejected as implausible, "
                              f"{g.get('constraints_broken', 0)} breaking the constraints, "
                              f"{g.get('drag_not_monotone', 0)} with drag not growing with speed, "
                              f"{g.get('no_evolved_term_left', 0)} with no evolved term left after the guards.")
            doc.table(["run", "seed", "e_d train", "e_d test", "e_c train", "e_c test", "qualified", "wall (s)"],
                      [[str(i + 1) + (mark if i == chosen else ""), r.get("seed"),
                        fmt(r.get("rmse_train")), fmt(r.get("rmse_test")), fmt(r.get("constraint_rmse_train")),
                        fmt(r.get("constraint_rmse_test")), "yes" if r.get("qualified") else "no",
                        fmt(r.get("wall_s"), 3)] for i, r in enumerate(tr["runs"])])
        if has_series:
            doc.figure(fig_residuals(name, tr), f"{name}_residuals", "residual over time on the test data")
        if any(math.isfinite(to_float(r.get("rmse_test"))) for r in tr.get("runs") or []):
            doc.figure(fig_runs(name, tr), f"{name}_runs",
                       "runs sorted by test error; dashed: the empirical model's test error (cf. the paper's Figs. 2-3)")
        if cfg.get("constraints") != "none" and tr.get("runs"):
            fig = fig_pareto(name, tr, cfg.get("gamma"))
            if fig is not None:
                doc.figure(fig, f"{name}_pareto", "Pareto front of e_d^train vs e_c^train over the runs' archives")
    header, rows = horizon_rows(result.get("horizons") or {})
    if rows:
        h = result["horizons"]
        doc.heading("Multi-step prediction on the test flights")
        doc.paragraph(f"From every test sample the model's velocity is integrated (RK4, steps of "
                      f"{h['dt_s']:.3g} s) with every other input read from the log; RMSE against the "
                      f"logged velocity per horizon (see docs/use-the-model.md for the exact metric).")
        doc.table(header, rows)
        for name, png in horizon_figures(h).items():
            doc.png(png, name, "multi-step prediction: error against horizon" if "error" in name
                    else "predicted velocity traces over the measured one")
    vers = result.get("versions") or {}
    doc.paragraph("Versions: " + ", ".join(f"{k} {v}" for k, v in vers.items()))
    return doc


def write(result: dict, directory) -> dict[str, Path]:
    """Write result.json, report.md, report.html and the PNGs into ``directory`` (atomically)."""
    return document(result).write(directory, "report", data={"result.json": result})


def compact(result: dict) -> dict:
    """The result without bulky parts (series, archives, the model): for ``--json`` output."""
    out = {k: v for k, v in result.items() if k != "targets"}
    out["targets"] = {}
    for name, tr in result["targets"].items():
        t = {k: v for k, v in tr.items() if k not in ("test_series", "model", "runs")}
        t["runs"] = [{k: v for k, v in r.items() if k != "archive"} for r in tr.get("runs") or []]
        out["targets"][name] = t
    return out
