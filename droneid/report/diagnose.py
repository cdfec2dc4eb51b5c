"""Rendering of a :class:`droneid.diagnosis.diagnose.DiagnosisResult`: terminal summary, JSON, Markdown/HTML.

Pure functions over the result (no printing); :func:`write` writes ``diagnosis.json``,
``diagnosis.md``, ``diagnosis.html`` and the figures' PNGs atomically into a folder.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from priors.effects import CATALOGUE

from droneid.diagnosis.result import DiagnosisResult
from droneid.errors import MissingSignalError
from droneid.logs.flight import canonical_unit
from droneid.report.document import Document, break_gaps, fmt, new_figure

__all__ = ["text", "document", "write"]

_MAX_POINTS = 3000


def _pair(d, key="train"):
    v = d.get(key)
    return fmt(v, 4) if v is not None else "—"


def _evidence_text(ev, verdict: str | None = None) -> str:
    """The decision rule's own line (training flights only; :class:`droneid.fitting.decide.Decision`),
    with ``verdict`` in place of its last word(s) when the diagnosis did something else with a
    candidate that passed (not added, dropped later). The test flights are NOT in this line:
    :func:`_test_text` says what they show, on a line of its own."""
    if ev.get("text"):
        line = ev["text"]
    else:   # a document without the rule's line (older diagnosis.json)
        line = (f"CV RMSE {fmt(ev['cv_rmse_before'], 4)} -> {fmt(ev['cv_rmse_after'], 4)} "
                f"({-100 * ev['rel_improvement']:+.1f} %), sign-flip p = {fmt(ev['p_value'], 2)} "
                f"(threshold {fmt(ev['p_threshold'], 2)}), {ev['blocks_improved']} blocks better: "
                + ("accepted" if ev.get("passed") else "rejected"))
    if verdict and line.endswith(": accepted"):
        line = line[: -len("accepted")] + verdict
    return line


def _test_text(ev) -> str | None:
    """The test flights' RMSE before and after, in words that cannot be read as part of the
    decision: "reported only, not part of the decision", and whether they got better or worse.
    None when there is no test error."""
    b, a = ev.get("test_rmse_before"), ev.get("test_rmse_after")
    if b is None or a is None or not b:
        return None
    pct = 100.0 * (a / b - 1.0)
    how = "better" if pct < -0.05 else "worse" if pct > 0.05 else "unchanged"
    return (f"test flights (reported only, not part of the decision): RMSE {fmt(b, 4)} -> "
            f"{fmt(a, 4)} m/s² over all targets ({pct:+.1f} %, {how} on the test flights)")


def _step_lines(ev, indent: str, label: str = "evidence (training flights, decides)") -> list[str]:
    lines = [f"{indent}{label}: {_evidence_text(ev)}"]
    tt = _test_text(ev)
    if tt:
        lines.append(f"{indent}{tt}")
    return lines


def _result(result) -> DiagnosisResult:
    """The one input kind: a DiagnosisResult as given, a diagnosis.json document read back."""
    return result if isinstance(result, DiagnosisResult) else DiagnosisResult.from_dict(result)


def _header_lines(r) -> list[str]:
    """The flights, the plan the diagnosis ran under, and the residual before any effect."""
    lines = [f"diagnosis of prior '{r.prior}' on train {', '.join(r.sources['train']) or '—'}"
             + (f" / test {', '.join(r.sources['test'])}" if r.sources.get("test") else " (no test flight)")]
    plan = (getattr(r, "plan", None) or {}).get("lines") or []
    if plan:
        lines.append("plan (the one identify makes on these flights, droneid.planning.plan):")
        lines.extend(f"  NOTE: {line}" for line in plan)
    lines.append("residual before (prior refit by least squares, no intercept), RMSE m/s²:")
    for t, v in r.targets.items():
        lines.append(f"  {t:7s} train {_pair(v['rmse_before'])}  test {_pair(v['rmse_before'], 'test')}"
                     f"  cv {_pair(v['rmse_before'], 'cv')}   (prior as given: train "
                     f"{_pair(v['rmse_prior'])}, test {_pair(v['rmse_prior'], 'test')})")
    return lines


def text(result) -> str:
    """The terminal summary of a diagnosis (a DiagnosisResult or its diagnosis.json)."""
    r = _result(result)
    lines = _header_lines(r)
    if r.steps:
        lines.append("effects added, in order:" if r.effects_added else
                     "effects added: none in the end (every step below was dropped at the end)")
        prev = {t: v["rmse_before"] for t, v in r.targets.items()}
        for i, s in enumerate(r.steps, 1):
            dropped = bool(s.get("dropped"))
            lines.append(f"  {i}. {s['effect']}: {s['physical']}"
                         + (" — DROPPED at the end, not in the final model" if dropped else ""))
            if s.get("tested_jointly"):
                lines.append(f"       tested jointly: {' + '.join(s['tested_jointly'])} (neither "
                             "passed alone; overlapping effects)")
            for t, e in s["rmse"].items():
                lines.append(f"       {t:7s} train {_pair(prev[t])} -> {_pair(e)}, "
                             f"test {_pair(prev[t], 'test')} -> {_pair(e, 'test')}")
                prev[t] = e
            lines.extend(_step_lines(s["evidence"], "       ", "evidence when added (training flights, decides)"
                                     if dropped else "evidence (training flights, decides)"))
            if dropped:
                lines.append("       dropped at the end: it no longer earns its place once the others are "
                             f"in: {_evidence_text(s['dropped'])}")
            alts = s["evidence"].get("indistinguishable_from") or []
            if alts:
                lines.append(f"       note: these data cannot tell it apart from {', '.join(alts)}")
        if len(r.final_effects) > 1:
            lines.append("final estimates (all effects refitted jointly):")
            for fe in r.final_effects:
                lines.append(f"  {fe['effect']}: {fe['physical']}")
        lines.append("residual after, RMSE m/s²:")
        for t, v in r.targets.items():
            lines.append(f"  {t:7s} train {_pair(v['rmse_after'])}  test {_pair(v['rmse_after'], 'test')}"
                         f"  cv {_pair(v['rmse_after'], 'cv')}")
    else:
        lines.append("effects added: none")
    if r.candidates:
        lines.append("every decision (one rule, droneid.fitting.decide: one-sided sign-flip test over the "
                     "validation blocks, Holm over every candidate the diagnosis may try; training "
                     "flights only):")
        for c in r.candidates:
            head = (f"  assessed on its own rows ({c['assessed']}):" if c.get("assessed")
                    else f"  step {c['step']}:")
            lines.append(head)
            chosen = _chosen(c, r)
            for sc in c["scores"]:
                lines.append(f"    {_candidate_text(sc, sc['effect'], chosen)}")
            if c.get("pairs"):
                lines.append(f"    {c['pairs_reason']}:")
                for pb in c["pairs"]:
                    lines.append(f"    {_candidate_text(pb, ' + '.join(pb['effects']), chosen)}")
    lines.append(r.conclusion)
    for note in getattr(r, "notes", []) or []:
        lines.append(f"WARNING: {note}")
    folded = [fe for fe in r.final_effects if fe.get("foldable")]
    if r.final_effects:
        lines.append("foldable into the model: " + (", ".join(fe["effect"] for fe in folded) or "none")
                     + "".join(f"; {fe['effect']} not ({fe['reason']})"
                               for fe in r.final_effects if not fe.get("foldable")))
    if r.not_detected:
        lines.append(f"tested, not in the final model: {', '.join(r.not_detected)}")
    if r.untestable:
        lines.append("untestable from these signals (NOT evidence of absence):")
        for eid, why in r.untestable.items():
            lines.append(f"  {eid}: {why}")
    if getattr(r, "not_applicable", None):
        lines.append("not applicable to this prior / these targets:")
        for eid, why in r.not_applicable.items():
            lines.append(f"  {eid}: {why}")
    lines.extend(_fallback_lines(r.open_ended or {}))
    lines.extend(symbol_lines(lines))
    return "\n".join(lines)


def _chosen(entry, r) -> str | None:
    """What a logged step added ("a" or "a + b"; None: nothing). Read from the entry, or for a
    diagnosis.json written before entries recorded it, from the steps in order."""
    if "added" in entry:
        return " + ".join(entry["added"]) if entry["added"] else None
    if entry.get("assessed"):
        return entry["assessed"] if entry["assessed"] in [s["effect"] for s in r.steps] else None
    regular = [s for s in r.steps if s["effect"] not in
               {c["assessed"] for c in r.candidates if c.get("assessed")}]
    k = entry["step"] - 1
    if 0 <= k < len(regular):
        s = regular[k]
        return " + ".join(s["tested_jointly"]) if s.get("tested_jointly") else s["effect"]
    return None


def _candidate_text(sc, name: str, chosen: str | None) -> str:
    """One candidate's decision line, its verdict saying what happened to it: added, or passed
    the rule but not added (and why), or rejected (the rule's own reasons)."""
    line = sc.get("text") or name
    if not sc.get("passed"):
        return line
    if chosen == name:
        return _evidence_text(sc, "accepted: added")
    if chosen is None:
        why = ("not added: the candidate with the lowest held-out error failed the rule, so the step "
               "stops (a weaker candidate may stand in for it)")
    else:
        why = f"not added: {chosen} was added at this step (the lowest held-out error)"
    return _evidence_text(sc, f"passes the rule, {why}")


def _verdict(sc, name: str, chosen: str | None) -> str:
    """One word or three for a candidate: added, passes (not added), rejected."""
    if not sc.get("passed"):
        return "rejected"
    return "added" if chosen == name else "passes the rule, not added"


#: every symbol or abbreviation the summary may print, with its meaning (printed when it appears)
GLOSSARY = (
    (r"\bCV\b", "CV: blocked cross-validation on the training flights (each validation block is "
                 "predicted by a model fitted on the other blocks)"),
    (r"CV RMSE \d", "CV RMSE in a decision line: root mean square of the held-out residuals, pooled "
                    "over the targets, each divided by its RMSE after the prior refit (so no unit)"),
    (r"\bσ\b", "σ: the RMSE of a target's residual after the prior refit (m/s²)"),
    (r"\bt = ", "t: the paired t statistic of the per-block gains, ln(held-out MSE without / with the "
                "candidate) in each block (reported; the decision uses the sign-flip p)"),
    (r"sign-flip p", "sign-flip p: one-sided p that the candidate does not help, from the per-block gains "
                     "(share of random sign patterns whose mean reaches the observed one)"),
    (r"α", "α: the family-wise error level over every candidate the diagnosis may try"),
    (r"Bonferroni over", "Bonferroni over m: the first effect must reach p < α/m, m = every candidate "
                         "the diagnosis may try (singles and pairs)"),
    (r"Holm rank", "Holm rank k of m: the k-th effect added must reach p < α/(m − k + 1)"),
    (r"blocks better", "n/B blocks better: validation blocks (of B) whose held-out error falls"),
    (r"\bG\b|dG/dt", "G: the prior's thrust-direction term for the target (m/s²): its tilt terms or "
                      "the logged thrust along body z; dG/dt its time derivative"),
    (r"τ", "τ: the attitude delay (s)"),
    (r"\bk_D\b", "k_D: the fitted linear drag (1/s)"),
    (r"c_D/m", "c_D/m: quadratic drag over mass (1/m), drag acceleration c_D/m·|v|v"),
    (r"c_Dz/m", "c_Dz/m: vertical quadratic drag over mass (1/m)"),
    (r"\bk_x\b|\bk_y\b", "k_x, k_y: linear drag along the body's forward and left axes (1/s)"),
    (r"\bR/4h\b|rotor radius R", "R: rotor radius (m); h: height above the ground (m)"),
    (r"\bh0\b", "h0: the height scale of the ground-effect precondition (m)"),
    (r"ω", "ω: rotor speed"),
    (r"T̄|T/T", "T: the logged thrust proxy; T̄: its training mean"),
    (r"ΔV/V̄", "ΔV/V̄: battery voltage change relative to its training mean"),
    (r"\bk_i\b", "k_i: thrust coefficient of motor i relative to the mean of all motors"),
    (r"a = -?\d", "a: how far the thrust exponent departs from 2 (thrust ∝ ω^(2 − a))"),
)


def symbol_lines(lines) -> list[str]:
    """"symbols:" and one line per symbol of :data:`GLOSSARY` that appears in ``lines``."""
    body = "\n".join(lines)
    found = [meaning for pattern, meaning in GLOSSARY if re.search(pattern, body)]
    return (["symbols:"] + [f"  {m}" for m in found]) if found else []


def _fallback_lines(open_ended) -> list[str]:
    """The open-ended fallback: a significant residual left after the catalogue is said so, with
    the SNGP term that explains it and its evidence; otherwise one line."""
    ran = {t: o for t, o in open_ended.items() if o and o.get("ran")}
    passed = {t: o for t, o in ran.items() if o.get("passed")}
    if not ran:
        why = next((o.get("reason") for o in open_ended.values() if o), "no targets")
        return [f"open-ended search: not run ({why})"]
    if not passed:
        return ["open-ended search: no significant residual remains after the catalogue "
                f"({', '.join(ran)}: no SNGP term passes the same rule)"]
    out = ["a SIGNIFICANT RESIDUAL REMAINS after the catalogue (no catalogue effect explains it; "
           "none was added in its place): the open-ended search explains it with"]
    for t, o in passed.items():
        out.append(f"  {t}: {o['equation']}")
        out.extend(_step_lines(o["evidence"], "       "))
    return out


def _with_unit(name: str) -> str:
    """An axis label: the signal name with its unit ("t (s)", "vz (m/s)"); the name alone where
    the unit is unknown (a derived quantity such as ``dG/dt``)."""
    if name == "t":
        return "t (s)"
    if name == "|v| v_axis":
        return "|v| v_axis (m²/s²)"
    try:
        unit = canonical_unit(name)
    except MissingSignalError:
        return name
    return f"{name} ({'dimensionless' if unit == '1' else unit})"


def _thin(n):
    return np.arange(n) if n <= _MAX_POINTS else np.linspace(0, n - 1, _MAX_POINTS).astype(int)


def document(result) -> Document:
    """The Markdown/HTML report with plots (residual over time, residual vs explaining signals,
    RMSE bars per step; the time-series figures only when the result holds its series)."""
    r = _result(result)
    doc = Document("Diagnosis: what the model lacks")
    doc.paragraph(f"Prior: {r.prior}. Training flights: {', '.join(r.sources['train'])}. Test flights: "
                  f"{', '.join(r.sources.get('test') or []) or 'none (cross-validation only)'}.")
    doc.paragraph(r.conclusion)
    plan = (getattr(r, "plan", None) or {}).get("lines") or []
    if plan:
        doc.paragraph("The plan (the one identify makes on these flights): " + "; ".join(plan) + ".")
    doc.paragraph("Effects are chosen on the training flights only (blocked cross-validation); "
                  "test-flight errors are reported, never used for a choice.")
    for note in getattr(r, "notes", []) or []:
        doc.paragraph(f"WARNING: {note}")
    doc.heading("Errors before and after (RMSE, m/s²)")
    rows = []
    for t, v in r.targets.items():
        rows.append([t, "prior as given", fmt(v["rmse_prior"]["train"]), fmt(v["rmse_prior"]["test"]), "—"])
        rows.append([t, "prior refit", fmt(v["rmse_before"]["train"]), fmt(v["rmse_before"]["test"]),
                     fmt(v["rmse_before"]["cv"])])
        for i, s in enumerate(r.steps, 1):
            e = s["rmse"][t]
            rows.append([t, f"+ {s['effect']}", fmt(e["train"]), fmt(e["test"]), fmt(e["cv"])])
    doc.table(["target", "model", "train", "test", "blocked CV"], rows)
    if r.steps:
        doc.heading("Effects added, in order")
        doc.table(["#", "effect", "physical terms", "evidence (training flights, decides)",
                   "test flights (reported only)"],
                  [[i, s["effect"] + (" (dropped at the end)" if s.get("dropped") else ""), s["physical"],
                    _evidence_text(s["evidence"])
                    + (f" (tested jointly: {' + '.join(s['tested_jointly'])})" if s.get("tested_jointly") else ""),
                    _test_text(s["evidence"]) or "—"]
                   for i, s in enumerate(r.steps, 1)])
        rows = [[fe["effect"], t, f["name"], str(f["expr"]), fmt(f["coefficient"], 4)]
                for fe in r.final_effects for t, fs in fe.get("features", {}).items() for f in fs]
        if rows:
            doc.heading("Foldable features (constants fixed from training)")
            doc.table(["effect", "target", "feature", "expression", "coefficient"], rows)
        nf = [[fe["effect"], fe["reason"]] for fe in r.final_effects if not fe.get("foldable", True)]
        if nf:
            doc.table(["not foldable", "why"], nf)
        if len(r.steps) > 1:
            doc.paragraph("Final estimates, all effects refitted jointly: "
                          + "; ".join(f"{fe['effect']}: {fe['physical']}" for fe in r.final_effects))
    if r.untestable:
        doc.heading("Untestable effects")
        doc.paragraph("These effects could not be tested with the logged signals; this is not evidence "
                      "that they are absent.")
        doc.table(["effect", "why"], [[k, v] for k, v in r.untestable.items()])
    if getattr(r, "not_applicable", None):
        doc.heading("Effects not applicable")
        doc.table(["effect", "why"], [[k, v] for k, v in r.not_applicable.items()])
    if r.candidates:
        doc.heading("Candidate scores per step")
        for c in r.candidates:
            chosen = _chosen(c, r)
            doc.table([f"step {c['step']}" if not c.get("assessed") else f"own rows ({c['assessed']})",
                       "CV error (σ units)", "CV change", "p", "threshold", "blocks better",
                       "test RMSE (reported only)", "decision"],
                      [[s["effect"], fmt(s["cv_rmse_after"]), f"{-100 * s['rel_improvement']:+.2f} %",
                        fmt(s["p_value"], 2), fmt(s["p_threshold"], 2), s["blocks_improved"],
                        fmt(s.get("test_rmse_after")), _verdict(s, s["effect"], chosen)] for s in c["scores"]])
            if c.get("pairs"):
                doc.paragraph(c["pairs_reason"])
                doc.table(["pair", "CV error (σ units)", "CV change", "p", "threshold", "decision"],
                          [[" + ".join(s["effects"]), fmt(s["cv_rmse_after"]),
                            f"{-100 * s['rel_improvement']:+.2f} %", fmt(s["p_value"], 2),
                            fmt(s["p_threshold"], 2), _verdict(s, " + ".join(s["effects"]), chosen)]
                           for s in c["pairs"]])
    if r.open_ended:
        doc.heading("Open-ended search on the residual")
        for t, o in r.open_ended.items():
            if o and o.get("ran") and o.get("passed"):
                doc.paragraph(f"{t}: a significant residual remains; the SNGP term below explains it. "
                              f"Evidence (training flights, decides): {_evidence_text(o['evidence'])}"
                              + (f". {_test_text(o['evidence'])}" if _test_text(o["evidence"]) else ""))
                doc.code(o["equation"])
            elif o and o.get("ran"):
                doc.paragraph(f"{t}: no significant residual remains (no SNGP term passes the rule; "
                              "none is shown)")
            elif o:
                doc.paragraph(f"{t}: not run ({o.get('reason')})")
    _figures(doc, r)
    return doc


def fig_residual_time(r):
    """Training residual over time per target, before and after the added effects; the lines
    break at gaps in time and between flights (:func:`droneid.report.document.break_gaps`)."""
    fig = new_figure(7.5, 2.2 * len(r.series) + 0.6)
    for i, (t, s) in enumerate(r.series.items()):
        ax = fig.add_subplot(len(r.series), 1, i + 1)
        tt, (before, after) = break_gaps(s["t"], [s["residual_before"], s["residual_after"]],
                                         flight=s["flight"])
        ax.plot(tt, before, lw=0.6, color="C3", label="before (prior refit)")
        if r.steps:
            ax.plot(tt, after, lw=0.6, color="C0", label="after")
        ax.set_ylabel(f"{t} residual (m/s²)")
        ax.legend(loc="upper right", fontsize=7)
    ax.set_xlabel("time (s)")
    return fig


def _figures(doc, r):
    if not r.series:
        return
    doc.heading("Residual over time")
    fig = fig_residual_time(r)
    doc.figure(fig, "residual_time", "Training residual of the refit prior before and after the added effects")
    for k, step in enumerate(r.steps, 1):
        eid = step["effect"]
        explain = getattr(CATALOGUE.get(eid), "explain_signal", "")
        fig = new_figure(7.5, 2.6 * len(r.series) + 0.6)
        for i, (t, s) in enumerate(r.series.items()):
            st = s["steps"][k - 1]
            res = np.asarray(st["residual"], float)
            contrib = np.asarray(st["contrib"], float) * np.ones_like(res)
            idx = _thin(res.size)
            ax = fig.add_subplot(len(r.series), 2, 2 * i + 1)
            lo, hi = float(np.min(contrib)), float(np.max(contrib))
            if hi - lo > 1e-12:
                ax.plot(contrib[idx], res[idx], ".", ms=2, alpha=0.5)
                ax.plot([lo, hi], [lo, hi], "k-", lw=1)
                ax.set_xlabel(f"fitted {eid} term (m/s²)")
                ax.set_ylabel(f"{t} residual before (m/s²)")
            else:  # a constant term: the residual's distribution and the fitted constant
                ax.hist(res, bins=40, color="C0", alpha=0.7)
                ax.axvline(lo, color="k", lw=1.5, label=f"fitted {eid} term")
                ax.axvline(0.0, color="C3", lw=1, ls="--", label="zero")
                ax.set_xlabel(f"{t} residual before (m/s²)")
                ax.set_ylabel("samples (count)")
                ax.legend(fontsize=7)
            ax2 = fig.add_subplot(len(r.series), 2, 2 * i + 2)
            xs = s["signals"].get(explain) if explain != "t" else s["t"]
            xname = explain
            if xs is None:
                xs, xname = s["t"], "t"
            xs = np.asarray(xs, float)
            ax2.plot(xs[idx], res[idx], ".", ms=2, alpha=0.4, label="residual before")
            ax2.plot(xs[idx], contrib[idx], ".", ms=2, alpha=0.6, label=f"{eid} term")
            ax2.set_xlabel(_with_unit(xname))
            ax2.set_ylabel("m/s²")
            ax2.legend(fontsize=7)
        doc.figure(fig, f"step{k}_{eid}", f"Step {k}: residual before the step against the fitted {eid} "
                                          f"term (left; points on the line = explained) and against {explain or 't'}")
    # before/after bars
    fig = new_figure(7.5, 3.0)
    labels = ["prior refit", *[f"+{s['effect']}" for s in r.steps]]
    width = 0.8 / (2 * len(r.targets))
    ax = fig.add_subplot()
    x = np.arange(len(labels))
    j = 0
    for t, v in r.targets.items():
        for role in ("train", "test" if v["rmse_before"].get("test") is not None else "cv"):
            vals = [v["rmse_before"][role]] + [s["rmse"][t][role] for s in r.steps]
            vals = [np.nan if a is None else a for a in vals]
            ax.bar(x + (j - len(r.targets) + 0.5) * width, vals, width, label=f"{t} {role}")
            j += 1
    ax.set_xticks(x, labels, fontsize=8)
    ax.set_ylabel("RMSE (m/s²)")
    ax.legend(fontsize=7)
    doc.figure(fig, "rmse_steps", "RMSE before and after each step")


def write(result, directory) -> dict[str, Path]:
    """Write diagnosis.json, diagnosis.md, diagnosis.html and PNGs into ``directory`` (atomic)."""
    r = _result(result)
    return document(r).write(directory, "diagnosis", data={"diagnosis.json": r.to_dict()})
