"""Rendering identify's rotational stage (result.json's ``rotation``, :mod:`droneid.rotation_stage`):
the per-axis verdicts, the candidates' validation, and the whole vehicle open loop on the test
flights (the nanodrone benchmark's metric) as a table and as drift against the horizon."""
from __future__ import annotations

from collections.abc import Mapping

from ..rotation_stage import RotationResult
from .document import Document, fmt, new_figure, text_table
from .wording import VERDICT_KINDS

__all__ = ["rotation_lines", "rotation_section", "open_loop_table", "fig_open_loop_drift"]

_QUANTITIES = (("position", "m"), ("velocity", "m/s"), ("attitude", "rad"), ("rates", "rad/s"))
_SHOWN = ("1", "10", "50")
#: how droneid/rotation.py's term names read (s_i = (rotor speed / 1000 rad/s)², P the layout's patterns)
_TERM_TEXT = {"damping": "(−ω)", "pattern": "(P s)", "centre": "Σs", "rotor_drag": "v_b", "gyro": "ω_j ω_l",
              "spinup": "(P ṡpin)", "rotor_drag_thrust": "v_b Σs", "attitude": "(−(θ − θ0))"}


def _axes_table(rot: RotationResult) -> tuple[list[str], list[list[str]]]:
    header = ["target", "validation: held", "validation: model", "test: held", "test: model", "verdict"]
    rows = [[a.target, fmt(a.validation_held), fmt(a.validation_model), fmt(a.test_held), fmt(a.test_model),
             a.verdict_kind] for a in rot.axes]
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
        parts.append(f"{ax} = {' '.join(terms) or '0'} ({a.rung})")
    return "rotational model (rad/s²): " + "; ".join(parts)


def open_loop_table(ol: Mapping) -> tuple[list[str], list[list[str]]]:
    """(header, rows): per model MAE at 1, 10, 50 steps and SimErr for the four quantities."""
    header = ["model", "horizon"] + [f"{q} ({u})" for q, u in _QUANTITIES]
    rows = [[m, "SimErr" if h == "simerr" else f"{h} steps"] + [fmt(per[h][q]) for q, _ in _QUANTITIES]
            for m, per in ol.items() for h in (*_SHOWN, "simerr") if h in per]
    return header, rows


def rotation_lines(rot: RotationResult | None) -> list[str]:
    """The terminal section: verdicts, layout, model, per-axis table, open loop on the test flights."""
    if rot is None:
        return []
    out = ["", "== rotation: ω̇x, ω̇y, ω̇z (body FLU), against the nominal rigid body with the rates held",
           *(a.verdict for a in rot.axes),
           f"rotor layout {rot.layout}: {rot.layout_source}; {rot.speed_note}", _model_line(rot)]
    header, rows = _axes_table(rot)
    out += [text_table(header, rows),
            "body-rate SimErr per axis (Σ over 1..50 steps of the mean |Δω|, rad/s), open loop; validation: each "
            "training flight held out in turn (the choice); test: the test flights (never part of a choice)"]
    out += [f"NOTE: {n}" for n in rot.notes]
    if rot.open_loop_test:
        header, rows = open_loop_table(rot.open_loop_test)
        out += ["", "== the whole vehicle open loop on the test flights (the nanodrone benchmark's metric: MAE over "
                    "every start, SimErr = Σ over 1..50 steps)", text_table(header, rows)]
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
    doc.paragraph(f"Rotor layout {rot.layout}: {rot.layout_source}. {rot.speed_note}.")
    doc.code(_model_line(rot))
    header, rows = _axes_table(rot)
    doc.table(header, rows)
    doc.paragraph("Body-rate SimErr per axis: Σ over 1..50 steps of the mean |Δω| (rad/s), simulated open loop "
                  "from the motor speeds. Validation holds each training flight out in turn (this is what "
                  "chooses); the test flights are scored after the choice. The baseline is the nominal rigid "
                  "body with the body rates held (ω̇ = 0).")
    for n in rot.notes:
        doc.paragraph(f"NOTE: {n}")
    if rot.open_loop_test:
        doc.heading("The whole vehicle open loop on the test flights", level=3)
        header, rows = open_loop_table(rot.open_loop_test)
        doc.table(header, rows)
        fig = fig_open_loop_drift(rot.open_loop_test)
        if fig is not None:
            doc.figure(fig, "open_loop_drift", "position and attitude error against the horizon, open loop "
                                                        "from the motor speeds (identified, nominal physics, state held)")
