"""``droneid predict`` for people: per target the error table (m/s²) of the identified model next to
the empirical model's, then the multi-step prediction table, from a
:class:`~droneid.use.score.Score`."""
from __future__ import annotations

from droneid.report.document import fmt, text_table
from droneid.report.rollout import ONE_STEP_POSITION
from droneid.report.rotation import open_loop_legend, open_loop_verdict
from droneid.use.transfer import constants_line

__all__ = ["text"]

#: one name per model across identify, predict, the plots and the docs: the final model, the
#: empirical model (as given) and the prior refit (:class:`~droneid.use.score.Errors` fields)
_LABELS = {"rmse_identified": "e_d final model", "rmse_empirical": "e_d empirical model",
           "rmse_refit": "e_d prior refit"}


def text(res) -> str:
    """The terminal report of a :class:`~droneid.use.score.Score`: one table per target, the
    horizon table when measured. The data-fitness warnings are not in it: the command prints them
    on standard error (a report redirected to a file must not hide them)."""
    out = []
    for t, r in res.targets.items():
        out.append(f"== {t}: {r.equation or '(model)'}")
        if r.use != "identified":
            out.append(f"USE {'THE EMPIRICAL MODEL' if r.use == 'empirical' else 'NEITHER MODEL'} for {t}: "
                       f"identify's verdict: {r.verdict.split(': ', 1)[-1] if r.verdict else r.use}")
        first = next(iter(r.errors.values()))
        keys = [k for k in _LABELS if getattr(first, k) is not None]
        header = ["data", "samples"] + [_LABELS[k] for k in keys]
        rows = [[name, str(e.n)] + [fmt(getattr(e, k)) for k in keys] for name, e in r.errors.items()]
        out.append(text_table(header, rows))
        if r.constants:
            out.append(constants_line(r.constants))
        for src, counts in r.screened.items():
            out.append(f"screened: {src}: " + ", ".join(f"{n} {c}" for n, c in counts.items())
                       + " implausible sample(s) or jump(s); rows that use them are not scored")
        for src, fr in r.out_of_range.items():
            out.append(f"unlike the training data: {src}: " + ", ".join(
                f"{n} outside its training range on {100 * v:.1f} % of the samples" for n, v in fr.items())
                + " (the model extrapolates there)")
        out += [f"note: {note}" for note in r.notes]
        out.append(f"errors: RMSE in m/s²; targets by {res.method} differences at Ts = {res.ts} s "
                   f"(as at identification)\n")
    if res.horizons is not None:
        info = res.horizon_info
        out.append(f"== multi-step prediction: RK4 at dt = {fmt(info['dt_s'])} s; velocities of the modelled "
                   f"axes integrated, every other signal from the log")
        tables = {m: {h: e.to_dict() for h, e in per.items()} for m, per in res.horizons.items()}
        cols = [k for k in ("vx", "vy", "vz", "position")
                if any(k in e for per in tables.values() for e in per.values())]
        header = ["model", "steps", "s", "starts"] + [f"{k} (m)" if k == "position" else f"{k} (m/s)" for k in cols]
        rows = [[m, str(h), fmt(h * info["dt_s"]), str(info["n_starts"][str(h)])]
                + [fmt(e.get(k)) for k in cols]
                for m, per in tables.items() for h, e in per.items()]
        out.append(text_table(header, rows))
        out.append("errors: RMSE at the horizon over every start (skipped starts: "
                   + ", ".join(f"{h} steps: {n}" for h, n in info["skipped"].items()) + ")")
        out.append(ONE_STEP_POSITION[0].upper() + ONE_STEP_POSITION[1:] + "\n")
    if res.open_loop is not None:
        out += open_loop_lines(res.open_loop_table(), res.open_loop_rotation, res.open_loop_inputs)
    return "\n".join(out)


def open_loop_lines(ol: dict, rotation: bool = False, motor: str = "") -> list[str]:
    """The open-loop table: per model, MAE at each horizon and SimErr, for position (m), velocity
    (m/s), attitude (rad) and body rates (rad/s). ``rotation``: whether the identified row has a
    rotational model (else its body rates are held); ``motor``: the motor model a command-driven
    vehicle's rows are driven through (:meth:`droneid.simulation.motor_model.MotorModel.text`), ""
    for motor speeds."""
    qs = ("position", "velocity", "attitude", "rates")
    header = ["model", "horizon"] + [f"{q} ({u})" for q, u in zip(qs, ("m", "m/s", "rad", "rad/s"))]
    rows = [[m, "SimErr" if h == "simerr" else f"{h} steps"] + [fmt(e[q]) for q in qs]
            for m, per in ol.items() for h, e in per.items()]
    inputs = "the logged motor commands" if motor else "the motor speeds"
    return [f"== open loop (the nanodrone benchmark's metric): full state simulated from {inputs}, "
            "MAE over every start; SimErr = sum of MAE over 1..50 steps",
            *filter(None, [open_loop_verdict(ol, rotation)]), text_table(header, rows),
            *([f"motor model (identified; the identified row reads the commands through it, nominal physics "
               f"through its curve without lag): {motor}"] if motor else []),
            open_loop_legend(rotation, bool(motor)) + "\n"]
