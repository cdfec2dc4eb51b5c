"""``droneid export``: the final models of an identify result.json as Python, C, MATLAB or LaTeX;
with ``--vehicle``, the whole vehicle (6-DOF step function) as Python or C."""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from droneid.errors import ConfigError, DataError
from droneid.core.io_util import atomic_write_text
from droneid.core.lazy import lazy_module
from droneid.commands._common import options_text

_export = lazy_module("droneid.use.export")
_predict = lazy_module("droneid.use.predict")
_vehicle_export = lazy_module("droneid.use.vehicle_export")
_rotation = lazy_module("droneid.rotation.model")
_motor = lazy_module("droneid.simulation.motor_model")
_gains = lazy_module("droneid.rotation.gains")


def register(sub) -> None:
    p = sub.add_parser("export",
                       description="Write each target's final model (targets.<t>.final of an identify "
                                   "result.json: prior terms, effects and evolved terms expanded into one "
                                   "expression) as self-contained code; the header states the inputs, units, "
                                   "conventions and delays. With --vehicle: the whole vehicle instead, a step "
                                   "function of the state and the motor speeds. See docs/use-the-model.md.")
    p.add_argument("result", metavar="RESULT.json", help="result.json of droneid identify")
    p.add_argument("--to", required=True, choices=("python", "c", "matlab", "latex"), help="output language")
    p.add_argument("-o", "--output", default=None, metavar="FILE",
                   help="write to FILE (atomically) instead of stdout; for matlab the file name "
                        "(without .m) is the function name")
    p.add_argument("--target", default=None, help="target(s), comma separated (default: every final model)")
    p.add_argument("--identified", action="store_true",
                   help="export the identified model of every target even where identify's verdict says to keep "
                        "the empirical model or neither (result.json targets.<t>.use); without it such a target "
                        "is exported as the empirical model as given, a target whose verdict keeps neither is "
                        "left out, and --vehicle is refused")
    p.add_argument("--vehicle", action="store_true",
                   help="the whole vehicle (python or c): the final vx_dot, vy_dot, vz_dot models and the "
                        "result's rotational model (rotation.model; null: the body rates held), stepped by RK4 "
                        "from the state and the logged motor speeds, as predict --open-loop simulates it. "
                        "The motor speeds drive the thrust; a body axis answers them only where its "
                        "rotational model has a torque term (the header says which axes do not). A "
                        "command-driven vehicle is fed its logged motor commands and battery voltage through "
                        "the identified motor model (thrust curve, battery compensation, motor lag), which also "
                        "gives its rotational model each rotor's thrust (as a fraction of full thrust)")
    p.add_argument("--allow-unsteerable", action="store_true",
                   help="with --vehicle: export even when a body axis does not answer the motors (its "
                        "rotational model is decay-only or held: differential thrust does not roll, pitch or "
                        "yaw it); without it such a vehicle is refused, as a plant for controller design "
                        "that cannot be steered is a trap")
    p.add_argument("--dt", type=float, default=None, metavar="SECONDS",
                   help="with --vehicle: the step the motor speeds are fed at; the delays are whole steps "
                        "of it (default: the training logs' step the rotational model was fitted at, rotation.dt_s; "
                        "without a rotational stage, the grid the v̇ models were identified on, config.ts)")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.vehicle:
        text = _vehicle(args)
    else:
        if args.dt is not None:
            raise ConfigError("--dt applies to --vehicle only (the v̇ equations hold no step)")
        text = _equations(args)
    if args.output:
        atomic_write_text(args.output, text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0


def _source(path, models: dict) -> str:
    # the reader options the model was identified with: a user's own CSV columns (--column),
    # MCAP topics, Motive body: what a reader of the header needs to feed the same signals
    read_with = options_text(models.get("_reader_options") or {})
    return f"{path} (logs read with {read_with})" if read_with else str(path)


def _provenance(path):
    return json.loads(Path(path).read_text(encoding="utf-8")).get("provenance")


def _equations(args) -> str:
    targets = [t.strip() for t in args.target.split(",")] if args.target else None
    models = _predict.load_models(args.result, targets)
    chosen, notes, left_out = [], [], []
    for t, m in models.items():
        if t.startswith("_") or "identified" not in m:
            continue
        use, said = m.get("use", "identified"), _verdict_words(m)
        if use == "identified":
            chosen.append(m["identified"])
        elif args.identified:
            chosen.append(m["identified"])
            notes.append(f"{t}: the IDENTIFIED model, exported with --identified although identify's verdict "
                         f"says to keep {'the empirical model' if use == 'empirical' else 'neither model'} ({said})")
        elif use == "empirical" and "empirical" in m:
            chosen.append(m["empirical"])
            notes.append(f"{t}: the EMPIRICAL model as given, as identify's verdict says ({said}); "
                         f"--identified writes the identified one")
        else:
            left_out.append(t)
            why = ("identify's verdict keeps neither model" if use == "neither" else
                   "identify's verdict keeps the empirical model, which the result does not hold")
            notes.append(f"{t}: not exported: {why} ({said}); --identified writes the identified one")
    if not chosen:
        if left_out:
            raise DataError(f"{args.result}: identify's verdicts keep no model of {', '.join(left_out)}; "
                            f"--identified exports the identified models anyway")
        raise DataError(f"{args.result}: no final model to export (targets.<t>.final is written by "
                        f"droneid identify; older results hold only the engine model)")
    for n in notes:
        print(f"note: {n}", file=sys.stderr)
    name = Path(args.output).stem if args.output and args.to == "matlab" else "droneid_model"
    return _export.export_models(chosen, args.to, source=_source(args.result, models), name=name,
                                 inputs=_export.input_sources(_provenance(args.result)), notes=notes)


def _verdict_words(m: dict) -> str:
    """The first sentence of a target's verdict without its target name, for a note."""
    text = str(m.get("verdict") or "").split(": ", 1)[-1]
    return text.split("; keep")[0].split(": keep")[0] or "no verdict recorded"


def _vehicle(args) -> str:
    if args.to not in _vehicle_export.VEHICLE_FORMATS:
        raise ConfigError(f"--vehicle writes python or c, not {args.to}")
    if args.target:
        raise ConfigError("--vehicle exports vx_dot, vy_dot and vz_dot together: drop --target")
    models = _predict.load_models(args.result)
    doc = json.loads(Path(args.result).read_text(encoding="utf-8"))
    motor = _motor.MotorModel.from_record(models.get("_config") or {})
    if not isinstance(doc.get("rotation"), dict) and motor is None:
        raise DataError(f"{args.result}: no rotational stage in the result ('rotation' is absent or null: "
                        "identified with --rotation none, by an older droneid, or from logs without body rates "
                        "and motor speeds); re-run droneid identify on such logs")
    finals = {t: models[t]["identified"] for t in ("vx_dot", "vy_dot", "vz_dot")
              if "identified" in models.get(t, {})}
    kept_other = [t for t in finals if models[t].get("use", "identified") != "identified"]
    for t in kept_other if args.identified else ():
        print(f"note: {t}: the IDENTIFIED model, exported with --identified although identify's verdict says to "
              f"keep {'the empirical model' if models[t]['use'] == 'empirical' else 'neither model'} "
              f"({_verdict_words(models[t])})", file=sys.stderr)
    missing = [t for t in ("vx_dot", "vy_dot", "vz_dot") if t not in finals]
    if missing:
        raise DataError(f"{args.result}: --vehicle needs the final models of vx_dot, vy_dot and vz_dot; "
                        f"the result has none of {', '.join(missing)}")
    # every reason to refuse, said at once (a user fixed one and met the next)
    refusals = []
    if kept_other and not args.identified:
        refusals.append(f"identify's verdict does not keep the identified model of {', '.join(kept_other)} "
                        f"({'; '.join(f'{t}: ' + _verdict_words(models[t]) for t in kept_other)}), so the vehicle "
                        f"built from it is not the one to use; --identified exports it anyway")
    stuck = _rotation.unsteerable(models.get("_rotation"))
    gains = _gains_note(doc) if stuck else ""
    replay = "logged motor commands" if motor is not None else "logged motor speeds"
    if stuck and not args.allow_unsteerable:
        if motor is not None and models.get("_rotation") is None:
            why = next((n for n in doc.get("notes") or () if str(n).startswith("rotation not modelled")),
                       "the rotational stage kept no model: every body rate is held")
            refusals.append(f"a command-driven vehicle without a rotational model ({why}), so the exported vehicle "
                            f"holds its body rates: its commands drive the thrust only and cannot steer it; "
                            f"--allow-unsteerable exports it anyway (for open-loop replay of {replay}, not for "
                            f"controller design)")
        else:
            refusals.append(f"the identified rotational model does not answer the motors on {', '.join(stuck)} "
                            f"(decay-only or held: differential thrust does not turn it), so the exported vehicle "
                            f"cannot be steered; --allow-unsteerable exports it anyway (for open-loop replay of "
                            f"{replay}, not for controller design)" + (f"; {gains}" if gains else ""))
    if refusals:
        raise DataError(f"{args.result}: " + (refusals[0] if len(refusals) == 1 else
                                              " ".join(f"({k}) {r}." for k, r in enumerate(refusals, 1))))
    dt, note = _step(args, doc)
    try:
        return _vehicle_export.export_vehicle(finals, models.get("_rotation"), args.to, source=_source(args.result, models),
                                      dt_s=dt, inputs=_export.input_sources(doc.get("provenance")),
                                      dt_note=note, motor=motor, gains_note=gains)
    except ConfigError as exc:
        raise ConfigError(f"{args.result}: {exc}") from None


def _gains_note(doc: dict) -> str:
    """One sentence on the vehicle's torque gains of the result (rotation.torque_gains), for a
    controller designer when the exported vehicle cannot be steered; "" without them."""
    record = (doc.get("rotation") or {}).get("torque_gains") if isinstance(doc.get("rotation"), dict) else None
    if not record:
        return ""
    try:
        g = _gains.TorqueGains.from_dict(record)
    except DataError:
        return ""          # a damaged record of what is only a pointer: the export itself stands
    return (f"the vehicle's torque gains for a controller design of your own are in the result "
            f"(rotation.torque_gains; {g.unit}): {g.text()}; {g.verdict()}")


def _step(args, doc) -> tuple[float, str]:
    """The step (s) and where it came from: --dt, else the logs' step identify recorded."""
    if args.dt is not None:
        if not (args.dt > 0 and math.isfinite(args.dt)):
            raise ConfigError(f"--dt must be a positive number of seconds, got {args.dt:g}")
        return float(args.dt), "given by --dt"
    sec = doc.get("rotation")
    dt = sec.get("dt_s") if isinstance(sec, dict) else None
    if isinstance(dt, (int, float)) and dt > 0:
        return float(f"{dt:.6g}"), "the training logs' step the rotational model was fitted at (rotation.dt_s); --dt to change it"
    ts = (doc.get("config") or {}).get("ts")
    if not isinstance(sec, dict) and isinstance(ts, (int, float)) and ts > 0:   # no rotational stage
        return float(f"{ts:.6g}"), "the grid the translational models were identified on (config.ts); --dt to change it"
    raise ConfigError(f"{args.result}: the result records no step for its rotational model (rotation.dt_s): "
                      "pass --dt SECONDS, the step of the logs the models were identified on")
