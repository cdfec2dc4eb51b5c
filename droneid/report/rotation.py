"""Rendering identify's rotational stage (result.json's ``rotation``, :mod:`droneid.rotation.stage`):
the per-axis verdicts, the candidates' validation, and the whole vehicle open loop on the test
flights (the nanodrone benchmark's metric) as a table and as drift against the horizon."""
from __future__ import annotations

import math

from collections.abc import Mapping

from droneid.fitting.constancy import constancy_line, rule_text
from droneid.rotation.model import AXIS_NAMES, unsteerable, unsteerable_sentence
from droneid.rotation.stage import RotationResult
from droneid.report.document import Document, fmt, new_figure, text_table
from droneid.report.rollout import ONE_STEP_POSITION
from droneid.fitting.verdict import VERDICT_KINDS
from droneid.fitting.decide import p_text
from droneid.simulation.drift import open_loop_verdict

__all__ = ["rotation_lines", "rotation_section", "open_loop_table", "open_loop_legend", "open_loop_verdict", "fig_open_loop_drift",
           "ladder_rows", "gains_lines"]

_QUANTITIES = (("position", "m"), ("velocity", "m/s"), ("attitude", "rad"), ("rates", "rad/s"))
_SHOWN = ("1", "10", "50")
#: how droneid/rotation/model.py's term names read (s_i = (rotor speed / 1000 rad/s)², P the layout's patterns)
_TERM_TEXT = {"damping": "(−ω)", "pattern": "(P s)", "centre": "Σs", "rotor_drag": "v_b", "gyro": "ω_j ω_l",
              "spinup": "(P ṡpin)", "rotor_drag_thrust": "v_b Σs", "attitude": "(−(θ − θ0))"}


def _axes_table(rot: RotationResult) -> tuple[list[str], list[list[str]]]:
    header = ["target", "validation: held", "validation: model", "test: held", "test: model", "verdict"]
    rows = [[a.target, fmt(a.validation_held), fmt(a.validation_model), fmt(a.test_held), fmt(a.test_model),
             a.verdict_kind] for a in rot.axes]
    return header, rows


def _decay_range(rot: RotationResult, k: int) -> str:
    """Axis ``k``'s decay evidence from the choice's damping row: its 95 % interval (block
    bootstrap of the training windows) and its range over the leave-one-flight-out refits."""
    for row in rot.choice.get("table", ()):
        if row.get("method") != "damping":
            continue
        parts = []
        if "damping_per_s_interval" in row:
            lo, hi = row["damping_per_s_interval"][k]
            top = max(row.get("damping_grid") or [math.inf])
            span = f"{lo:.3g} /s or more (the grid ends at {top:.3g} /s)" if hi >= top else f"{lo:.3g}-{hi:.3g} /s"
            parts.append(f"95 % bootstrap interval {span}")
        if "damping_per_s_range" in row:
            lo, hi = row["damping_per_s_range"][0][k], row["damping_per_s_range"][1][k]
            parts.append(f"{lo:.3g}-{hi:.3g} /s over the leave-one-flight-out refits")
        return f" [decay {'; '.join(parts)}]" if parts else ""
    return ""


def _spinup_evidence(rot: RotationResult) -> str:
    """The yaw spin-up rung's settings from the choice's spinup row: the motor-stream alignment
    and lag chosen on the training flights and the gain's 95 % block-bootstrap interval."""
    for row in rot.choice.get("table", ()):
        if row.get("method") == "spinup":
            lo, hi = row["gain_interval"]
            lag = "no motor lag" if row.get("lowpass_tau_s") is None else f"motor lag {1000 * row['lowpass_tau_s']:.3g} ms"
            return (f" [motor speeds {row['delay_steps']} step(s) earlier, {lag}; spin-up gain 95 % bootstrap "
                    f"interval {lo:.3g}-{hi:.3g}]")
    return ""


def _ladder_rule(rot: RotationResult) -> str:
    """How the ladder decides, with the test's α, Holm family and minimum effect as the choice
    recorded them."""
    first = next(iter(rot.choice.get("ladder") or ()), {})
    alpha, family = float(first.get("alpha", 0.01)), int(first.get("family_size", 1))
    min_effect = float(first.get("min_effect_pct", 1.0))
    return (f"a rung is taken when it lowers the axis's held-out SimErr against the rung the axis stands on below "
            f"it, consistently over the (held-out flight, regime) cells: one-sided sign-flip test of the cells' log "
            f"error ratios, Holm over the {family} axis-rung steps at α = {alpha:g} (p < threshold), and the pooled "
            f"SimErr at least {min_effect:g} % lower")


def _test_cell(st: Mapping) -> str:
    """A ladder step's test, readable: ``p 2e-05 < 0.0033 over 20 cells``."""
    if st.get("p_value") is None:
        return f"not tested ({st.get('cells', 0)} cells)"
    p, thr = float(st["p_value"]), float(st["threshold"])
    p_s, thr_s = p_text(p, thr)
    return f"p {p_s} {'<' if p < thr else '≥'} {thr_s} over {st['cells']} cells"


def _taken_cell(st: Mapping, min_effect_pct: float) -> str:
    """Whether a ladder step was taken and, when not, the rule's part that stopped it: a passing p
    with a pooled gain under the minimum read as 'no' with no reason (walkthrough)."""
    if st["taken"]:
        return "yes"
    if st.get("p_value") is None:
        return "no (not tested)"
    if float(st["p_value"]) >= float(st["threshold"]):
        return "no (p ≥ threshold)"
    eff = st.get("effect_pct")
    if eff is not None and float(eff) < min_effect_pct:
        return f"no (SimErr {-float(eff):+.2f} %: not {min_effect_pct:g} % lower)"
    return "no (a rung below not taken)" if st.get("accepted") else "no"


def ladder_rows(rot: RotationResult) -> tuple[list[str], list[list[str]]]:
    """(header, rows): each axis's ladder step by step, from the choice's ``ladder``: the rung
    against the one below, the held-out flight-regime cells where it is better, its error ratio
    per regime (calmest first), its pooled SimErr change, the rule's test (p, Holm threshold,
    cells) and whether it was taken."""
    header = ["axis", "rung", "against", "cells better", "error ratio by regime, calm to hard", "SimErr",
              "test (sign-flip, Holm)", "taken"]
    rows = []
    first = next(iter(rot.choice.get("ladder") or ()), {})
    min_effect = float(first.get("min_effect_pct", 1.0))
    for axis in rot.choice.get("ladder", ()):
        for st in axis["steps"]:
            cells = [w for row in st["wins"] for w in row if w is not None]
            ratio = ", ".join("—" if r is None else f"{r:.2f}" for r in st["ratio"])
            effect = "—" if st.get("effect_pct") is None else f"{-float(st['effect_pct']):+.1f} %"
            rows.append([axis["axis"], st["rung"], st["against"], f"{sum(cells)}/{len(cells)}", ratio, effect,
                         _test_cell(st), _taken_cell(st, min_effect)])
    return header, rows


def _model_line(rot: RotationResult) -> str:
    """The rotational model per axis, in rad/s²: its rung and the terms it kept."""
    m = rot.model
    parts = []
    for k, (ax, a) in enumerate(zip(("ω̇x", "ω̇y", "ω̇z"), rot.axes)):
        if m is None or a.rung == "held":
            parts.append(f"{ax} = 0 (rate held)")
            continue
        terms = [f"{c:+.4g}·{_TERM_TEXT.get(n, n)}" for n, c in zip(m.columns(k), m.coef[k]) if c != 0]
        if m.trim[k] != 0:
            terms.append(f"{m.trim[k]:+.4g}")
        evidence = _decay_range(rot, k) if a.rung == "damping" else _spinup_evidence(rot) if a.rung == "spinup" else ""
        parts.append(f"{ax} = {' '.join(terms) or '0'} ({a.rung})" + evidence)
    tail = unsteerable_sentence(unsteerable(m), "motor commands" if rot.from_commands else "motor speeds")
    return "rotational model (rad/s²): " + "; ".join(parts) + (f". {tail} (export --vehicle refuses it without "
                                                                 f"--allow-unsteerable)" if tail else "")


def gains_lines(rot: RotationResult) -> list[str]:
    """The vehicle's torque gains (:mod:`droneid.rotation.gains`), the verdict first: each axis's
    gain with its 95 % interval, which axes of the chosen model have a torque term, their
    constancy over the training flights, on the test flights, and each flight's conditions."""
    g = rot.torque_gains
    if g is None:
        return []
    used = [ax for k, ax in enumerate(AXIS_NAMES) if rot.axes[k].rung == "torque"]
    where = (f"the chosen model has a torque term on {', '.join(used)} (its own coefficient, fitted for open-loop "
             f"prediction)" if used else "the chosen model has no torque term (the ladder did not take the torque "
             "rung: integrated open loop, the torque model drifts in calm flight; the gains are what the motors do "
             "at the equation level)")
    floor = (" (a lower bound of 0 is the physics bound: the interval reached below it)"
             if any(lo <= 0.0 for _, lo, _ in g.gains.values()) else "")
    return [f"torque gains, {g.verdict()}: {g.text()}{floor} ({g.unit}, P the layout's torque pattern: per rotor "
            f"its y, −x and spin ±1: the motors' torque over the body's inertia; the torque rung's terms fitted at "
            f"the equation level, a trim per in-flight stretch, each flight at its own alignment and band; 95 % "
            f"interval: the hull of the (flight, block) bootstrap and the between-flight interval; noise on the "
            f"logged motor speeds pulls such a gain towards zero, not corrected: docs/use-the-model.md); {where}",
            *filter(None, [constancy_line(g.constancy), _tested_line(g), _conditions_line(g)])]


def _tested_line(g) -> str:
    """The torque gains on the test flights (reported, never chosen on): the verdict first."""
    if not g.tested:
        return ""
    bad = g.failing()
    judged = any(v[4] is not None for per in g.tested.values() for v in per.values())
    spread = any(c.constant is False for c in g.constancy.values())
    head = (f"DO NOT HOLD on the test flights ({', '.join(bad)}): not the vehicle's constants under this model"
            if bad else ("lie within the training flights' spread on the test flights" if spread else
                         "hold on the test flights") if judged else "cannot be tested on the test flights")
    parts = []
    for f, per in g.tested.items():
        cells = []
        for ax, (v, lo, hi, p, holds) in per.items():
            said = "not identifiable" if holds is None else f"p = {p:.2g}" + ("" if holds else ": DOES NOT HOLD")
            cells.append(f"{ax} {v:.3g} [{lo:.3g}, {hi:.3g}] ({said})")
        parts.append(f"{f}: " + ", ".join(cells))
    rule = rule_text("each flight fitted alone, against what a new flight of the vehicle should give; two-sided p")
    return f"  the torque gains {head} ({rule}; reported, never chosen on): " + "; ".join(parts)


def _conditions_line(g) -> str:
    """Each flight's own conditions of the torque gains (:func:`droneid.rotation.gains.flight_conditions`)."""
    if not g.conditions:
        return ""
    parts = [f"{f} {1000 * a:.3g} ms, " + ("all of it" if b is None else f"minus its ±{b:g} s moving average")
             for f, (a, b) in g.conditions.items()]
    return ("  each flight's conditions of its gains, chosen on that flight alone where the torque pattern explains "
            "most (the motor stream read that much earlier; the band, a high-pass: the slow part the controller "
            "spends on moments the model lacks taken off both sides): " + "; ".join(parts))


def open_loop_table(ol: Mapping) -> tuple[list[str], list[list[str]]]:
    """(header, rows): per model MAE at 1, 10, 50 steps and SimErr for the four quantities."""
    header = ["model", "horizon"] + [f"{q} ({u})" for q, u in _QUANTITIES]
    rows = [[m, "SimErr" if h == "simerr" else f"{h} steps"] + [fmt(per[h][q]) for q, _ in _QUANTITIES]
            for m, per in ol.items() for h in (*_SHOWN, "simerr") if h in per]
    return header, rows


def _has_rotation(rot: RotationResult) -> bool:
    """Whether the identified open-loop row has a rotational model (some axis not held)."""
    return rot.model is not None and any(a.rung != "held" for a in rot.axes)


def open_loop_legend(rotation: bool = True, commands: bool = False) -> str:
    """What the rows of the open-loop table are (one home: identify's text and report, predict),
    and why their 1-step position errors agree. ``rotation``: whether the identified row has a
    rotational model (else its body rates are held); ``commands``: the vehicle is driven by its
    logged motor commands (through the identified motor model), not by motor speeds."""
    return ("identified: the final v̇ models, attitude from the simulated quaternion, "
            + ("body rates from the identified rotational model" if rotation else
               "body rates held (no rotational model beat holding them, or none was identified)")
            + f"; nominal physics: thrust from the {'motor commands' if commands else 'motor speeds'} "
            "at the prior's nominal scale, no drag, "
            f"rates held; constant: the state held; {ONE_STEP_POSITION}")


def rotation_lines(rot: RotationResult | None) -> list[str]:
    """The terminal section: verdicts, layout, model, per-axis table, open loop on the test flights."""
    if rot is None:
        return []
    out = ["", "== rotation: ω̇x, ω̇y, ω̇z (body FLU), against the nominal rigid body with the rates held",
           *(a.verdict for a in rot.axes),
           f"rotor layout {rot.layout}: {rot.layout_source}; {rot.speed_note}", _model_line(rot), *gains_lines(rot)]
    header, rows = _axes_table(rot)
    out += [text_table(header, rows),
            "body-rate SimErr per axis (Σ over 1..50 steps of the mean |Δω|, rad/s), open loop; validation: each "
            "training flight held out in turn (the choice); test: the test flights (never part of a choice)"]
    header, rows = ladder_rows(rot)
    if rows:
        out += [text_table(header, rows), _ladder_rule(rot)]
    out += [f"NOTE: {n}" for n in rot.notes]
    if rot.open_loop_test:
        header, rows = open_loop_table(rot.open_loop_test)
        out += ["", "== the whole vehicle open loop on the test flights (the nanodrone benchmark's metric: MAE over "
                    "every start, SimErr = Σ over 1..50 steps)",
                *filter(None, [open_loop_verdict(rot.open_loop_test, _has_rotation(rot))]), text_table(header, rows),
                open_loop_legend(_has_rotation(rot), rot.from_commands)]
    return out


def fig_open_loop_drift(ol: Mapping):
    """Position and attitude MAE against the horizon, one line per model; None without the
    horizons 1..50."""
    steps = sorted(int(h) for h in next(iter(ol.values())) if h.isdigit())
    if len(steps) < 3:
        return None
    fig = new_figure(7.5, 3.0)
    for i, (q, unit) in enumerate((("position", "m"), ("attitude", "rad"))):
        ax = fig.add_subplot(1, 2, i + 1)
        for m, per in ol.items():
            ax.plot(steps, [per[str(h)][q] for h in steps], label=m)
        ax.set_xlabel("steps ahead (open loop)")
        ax.set_ylabel(f"{q} MAE ({unit})")
        ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def rotation_section(doc: Document, rot: RotationResult | None) -> None:
    """The report's rotation section: verdict per axis, the table, the open loop and its drift."""
    if rot is None:
        return
    doc.heading("Rotation: ω̇x, ω̇y, ω̇z")
    for a in rot.axes:
        doc.verdict(a.verdict, VERDICT_KINDS.get(a.verdict_kind, "grey"))
    doc.paragraph(f"Rotor layout {rot.layout}: {rot.layout_source}; {rot.speed_note}.")
    doc.code(_model_line(rot))
    for line in gains_lines(rot):
        doc.paragraph(line.strip()[:1].upper() + line.strip()[1:])
    header, rows = _axes_table(rot)
    doc.table(header, rows)
    doc.paragraph("Body-rate SimErr per axis: Σ over 1..50 steps of the mean |Δω| (rad/s), simulated open loop "
                  f"from the {'motor commands through the motor model' if rot.from_commands else 'motor speeds'}. "
                  "Validation holds each training flight out in turn (this is what "
                  "chooses); the test flights are scored after the choice. The baseline is the nominal rigid "
                  "body with the body rates held (ω̇ = 0).")
    header, rows = ladder_rows(rot)
    if rows:
        doc.paragraph(f"Each axis's ladder ((held-out training flight, regime of the held drift) cells, calm "
                      f"flight to hard manoeuvres): {_ladder_rule(rot)}.")
        doc.table(header, rows)
    for n in rot.notes:
        doc.paragraph(f"NOTE: {n}")
    if rot.open_loop_test:
        doc.heading("The whole vehicle open loop on the test flights", level=3)
        said = open_loop_verdict(rot.open_loop_test, _has_rotation(rot))
        if said:
            doc.paragraph(said)
        header, rows = open_loop_table(rot.open_loop_test)
        doc.table(header, rows)
        doc.paragraph(open_loop_legend(_has_rotation(rot), rot.from_commands))
        fig = fig_open_loop_drift(rot.open_loop_test)
        if fig is not None:
            doc.figure(fig, "open_loop_drift", "position and attitude error against the horizon, open loop "
                                                        "from the motor speeds (identified, nominal physics, state held)")
