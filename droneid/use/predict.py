"""Apply saved identified models to other logs and measure their error.

Accepts either an identification result (``result.json`` of ``droneid identify``) or a bare model
file (the engine's ``to_dict()``, with its target named by the caller). From a result, each
target's FINAL model (``targets.<t>.final``, an :class:`droneid.fitting.closed_form.IdentifiedModel`) is
evaluated next to the user's empirical model as given (``empirical_model``) and its least-squares
refit (``refit_model``); a bare model file is the engine's model alone. The data are built with the same sampling period and
differentiator the model was identified with; inputs with a delay are read at ``t − delay``.
``horizons`` adds multi-step prediction errors (:mod:`droneid.simulation.rollout`). The errors are typed
(:class:`droneid.use.score.Score`); :func:`final_predictions` gives the predictions themselves.
"""
from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from priors.registry import get_prior

from droneid.use.transfer import check_constants, identified_constants
from droneid.engine import runner
from droneid.dataset.builder import DatasetBuilder
from droneid.fitting.verdict import model_to_use
from droneid.errors import ConfigError, DataError, DroneIdError, check_choice
from droneid.core.expressions import compile_expression
from droneid.logs.flight import Flight, fingerprint
from droneid.dataset.suitability import assess
from droneid.fitting.closed_form import IdentifiedModel, check_schema
from droneid.core.targets import TARGETS, state_of
from droneid.core.numerics import rmse
from droneid.simulation.openloop import (Constant, IdentifiedTranslation, IdentifiedVehicle, NominalPhysics, flight_state_logs,
                       open_loop)
from droneid.rotation.model import RotationModel
from droneid.simulation.motor_model import MotorModel, NominalCommandPhysics, is_command
from droneid.rotation.stage import speed_scale
from droneid.simulation.rollout import rollout_errors, sample_inputs
from droneid.use.score import Errors, HorizonErrors, Score, TargetScore
from droneid.logs.screening import implausible_counts, screen_flight
from droneid.sngp import SymbolicModel

__all__ = ["load_models", "predict_flights", "model_sets", "open_loop_section", "final_predictions"]


def load_models(path, targets: Sequence[str] | None = None) -> dict:
    """{target: {"identified", "empirical", "refit" (IdentifiedModels) | "model" (a bare engine model),
    "inputs", "equation", ...}} plus "_config" and
    "_reader_options" (the reader options the result was identified with: read_flight keywords,
    ``{}`` when none were recorded) and "_trained" (its training flights' names, whose vehicle
    constants predict does not test against themselves) from a JSON file: an identify result.json (schema
    :data:`droneid.fitting.closed_form.SCHEMA`; an older one is refused with one line) or a bare model."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise DataError(f"{path}: not a JSON file ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(doc, dict):
        raise DataError(f"{path}: expected a JSON object (an identify result.json or a model file)")
    if "targets" in doc:
        return models_from_document(doc, targets, where=str(path))
    # a bare model file (SNGPRegressor.to_dict()): its target is saved in it or named by the caller
    target = targets[0] if targets and len(targets) == 1 else doc.get("target")
    if target not in TARGETS:
        raise ConfigError(f"{path} is a single model without a known target: name it with --target "
                          f"(one of {', '.join(TARGETS)})")
    inputs = doc.get("inputs")
    if not inputs:
        raise DataError(f"{path}: a model file must list its 'inputs'")
    return {target: {"model": doc, "inputs": list(inputs), "equation": doc.get("equation")}, "_config": {},
            "_reader_options": {}}


def models_from_document(doc: dict, targets: Sequence[str] | None = None, where: str = "the result") -> dict:
    """:func:`load_models` of an identify result document (``IdentificationResult.to_dict()``)."""
    check_schema(doc, where)
    if not isinstance(doc["targets"], dict):
        raise DataError(f"{where}: 'targets' must map target names to results")
    available = [t for t, tr in doc["targets"].items() if isinstance(tr, dict) and tr.get("final")]
    if not available:
        raise DataError(f"{where}: the result holds no finished model")
    chosen = list(targets) if targets else available
    for t in chosen:
        check_choice("target", t, available, owner=where)
    out = {t: _entry(where, t, doc["targets"][t]) for t in chosen}
    out["_config"] = doc.get("config") or {}
    out["_reader_options"] = _reader_options(where, doc.get("reader_options"))
    out["_rotation"] = _rotation_model(where, doc.get("rotation"))
    out["_trained"] = trained_names(doc.get("provenance"))
    out["_trained_data"] = trained_fingerprints(doc.get("provenance"))
    return out


def trained_fingerprints(provenance) -> frozenset[str]:
    """The data fingerprints (:func:`droneid.logs.flight.fingerprint`) of a result's training
    flights, from its ``provenance.train`` (empty for a result that did not record them)."""
    train = (provenance or {}).get("train") if isinstance(provenance, dict) else None
    return frozenset(str(p["fingerprint"]) for p in train or [] if isinstance(p, dict) and p.get("fingerprint"))


def trained_names(provenance) -> tuple[str, ...]:
    """The names (file stems, as a Flight is named) of a result's training flights, from its
    ``provenance.train`` (empty when it does not say)."""
    train = (provenance or {}).get("train") if isinstance(provenance, dict) else None
    names = []
    for p in train or []:
        for f in (p.get("files") or [])[:1] if isinstance(p, dict) else []:
            names.append(Path(str(f)).stem)
    return tuple(names)


def _rotation_model(where: str, section) -> RotationModel | None:
    """The identified rotational model of a result's ``rotation`` section, or None (none
    modelled, or the rates are held)."""
    if not section:
        return None
    if not isinstance(section, dict):
        raise DataError(f"{where}: 'rotation' must be an object")
    if section.get("model") is None:
        return None
    try:
        return RotationModel.from_dict(section["model"])
    except DroneIdError as exc:
        raise DataError(f"{where}: rotation.model: {exc}") from None


#: the reader options a result may record (identify's ``reader_options``: the read_flight keywords
#: of the CLI's --format, --topic, --body, --column, --sysid, --vehicle, --world-frame, --body-frame,
#: --time-unit, --scale), with each value's type
READER_OPTION_TYPES = {"format": str, "topics": dict, "body": str, "column_map": dict, "sysid": int,
                        "vehicle": str, "world_frame": str, "body_frame": str, "time_unit": str, "scales": dict}


_KIND_NAMES = {str: "a string", int: "an integer", dict: "a map of names to names"}


def _reader_options(path, recorded) -> dict:
    """The ``reader_options`` a result recorded (identify writes the options its logs were read
    with), checked: unset options are left out; a damaged entry is an error naming the file."""
    if recorded is None:
        return {}
    if not isinstance(recorded, dict):
        raise DataError(f"{path}: 'reader_options' must be an object of reader options, got "
                        f"{type(recorded).__name__}")
    out = {}
    for k, v in recorded.items():
        if v is None:
            continue
        kind = READER_OPTION_TYPES.get(k)
        if kind is None:
            raise DataError(f"{path}: reader_options.{k} is not a reader option (known: "
                            f"{', '.join(READER_OPTION_TYPES)})")
        ok = isinstance(v, kind) and not isinstance(v, bool)
        if ok and kind is dict:
            ok = all(isinstance(a, str) and isinstance(b, str) for a, b in v.items())
        if not ok:
            raise DataError(f"{path}: reader_options.{k} must be "
                            f"{_KIND_NAMES[kind]}, got {v!r}")
        if v != {}:
            out[k] = dict(v) if kind is dict else v
    return out


def _entry(path, target: str, tr: dict) -> dict:
    """One target of a result.json: its final, empirical and refit IdentifiedModels (errors name
    the file and the target), its equation and input ranges."""
    out = {"equation": tr.get("equation")}
    for key, name in (("final", "identified"), ("empirical_model", "empirical"), ("refit_model", "refit")):
        if tr.get(key):
            try:
                out[name] = IdentifiedModel.from_dict(tr[key])
            except DroneIdError as exc:
                raise DataError(f"{path}: targets.{target}.{key}: {exc}") from None
    out["equation"] = out["equation"] or f"{target} = {out['identified'].text()}"
    out["input_ranges"] = dict(tr.get("input_ranges") or {})
    out["constants"] = identified_constants(tr)
    out["verdict"] = str(tr.get("verdict") or "")
    out["use"] = model_to_use(str(tr.get("verdict_kind") or ""), str(tr.get("use") or ""), out["verdict"])
    if out["use"] not in ("identified", "empirical", "neither"):
        raise DataError(f"{path}: targets.{target}.use: {out['use']!r} is not identified, empirical or neither")
    return out


def model_sets(models: dict) -> dict:
    """{"identified"|"empirical"|"refit": {target: IdentifiedModel}} of the translational targets
    of :func:`load_models` output that hold final models (what multi-step prediction integrates)."""
    targets = set(TARGETS)
    sets: dict = {}
    for target, m in models.items():
        if target in targets and "identified" in m:
            for name in ("identified", "empirical", "refit"):
                if name in m:
                    sets.setdefault(name, {})[target] = m[name]
    return sets




def _nominal_physics(cfg: dict):
    """The benchmark's Physics row for the prior the result used (its parameters as recorded:
    hover-calibrated on the TRAINING flights): thrust from the logged inputs along the body z
    axis, no drag, rates held. The prior says what its thrust is (the magnitude of its v̇z
    thrust term, :attr:`priors.base.PriorFeature.magnitude`): one quadratic law in the rotor
    speeds (rpm1..) gives :class:`NominalPhysics`; a law in the commands (``motor<i>`` or
    ``throttle``, with ``battery_voltage`` where the curve compensates it) gives
    :class:`~droneid.simulation.motor_model.NominalCommandPhysics`. None for any other law, or where
    the prior cannot be rebuilt from the record."""
    try:
        prior = get_prior(str(cfg["prior_used"]), **dict(cfg["prior_params"]))
        feats = [f for f in prior.features("vz_dot") if f.role == "thrust" and f.magnitude is not None]
    except (KeyError, TypeError, DroneIdError):
        return None
    if len(feats) != 1:
        return None
    names = sorted(s.name for s in feats[0].magnitude.free_symbols)
    law = compile_expression(feats[0].magnitude, names) if names else None
    if names and any(is_command(n) for n in names) and all(is_command(n) or n == "battery_voltage" for n in names):
        return NominalCommandPhysics(law, tuple(names), float(cfg["prior_params"].get("g", 9.81)))
    if not names or not all(re.fullmatch(r"rpm\d+", n) for n in names):
        return None
    one, two = (float(law({n: np.full(1, u) for n in names})[0]) for u in (1.0, 2.0))
    if not (one > 0 and math.isclose(two, 4 * one, rel_tol=1e-9)):
        return None
    return NominalPhysics(thrust_coeff_N_s2=one / len(names), mass_kg=1.0, rad_s_per_rpm=1.0)


def open_loop_section(models: dict, flights: Sequence, horizons: Sequence[int] = (1, 10, 50)) -> dict:
    """The nanodrone benchmark's open-loop metric (:mod:`droneid.simulation.openloop`) on ``flights``:
    ``{"identified" | "nominal physics" | "constant": {"1": {"position", "velocity", "attitude",
    "rates"}, ..., "simerr": {...}}}`` over 50 steps at the log's rate from every start.
    "identified" drives the final v̇ models by the simulated state and the logged motor speeds
    (a command-driven vehicle: the logged commands and battery voltage through the result's motor
    model, :class:`~droneid.simulation.motor_model.MotorModel`: its thrust curve, compensation and
    lag), with the result's rotational model (``_rotation``: :mod:`droneid.rotation.stage`) or,
    without one, the body rates held; "nominal physics" is thrust from the same inputs with the
    prior's nominal (hover-calibrated on the TRAINING flights) thrust law, no drag, rates held;
    "constant" holds the state."""
    sets = model_sets(models)
    if "identified" not in sets:
        raise ConfigError("--open-loop needs the final models of vx_dot, vy_dot and vz_dot (targets.<t>.final)")
    cfg = models.get("_config") or {}
    translation = IdentifiedTranslation(sets["identified"], MotorModel.from_record(cfg))
    rotation = models.get("_rotation")
    if rotation is not None and rotation.commands is None:
        for f in flights:   # the rotational model reads rotor speeds in the unit it was fitted on
            scale, why = speed_scale(f)
            if not math.isclose(scale, rotation.rad_s_per_rpm, rel_tol=1e-9):
                raise DataError(f"{f.name}: the rotational model was identified on motor speeds at "
                                f"{rotation.rad_s_per_rpm:.6g} rad/s per logged unit; this log's are not ({why})")
    chosen = {"identified": translation if rotation is None else IdentifiedVehicle(translation, rotation)}
    nominal = _nominal_physics(cfg)
    if nominal is not None:
        chosen["nominal physics"] = nominal
    chosen["constant"] = Constant()
    signals = tuple(dict.fromkeys([*translation.signals(), *(nominal.signals() if hasattr(nominal, "signals") else ()),
                                   *(rotation.signals() if rotation is not None else ())]))
    return open_loop(chosen, flight_state_logs(flights, signals=signals), max_horizon=50,
                     horizons=tuple(h for h in horizons if h <= 50)).to_dict()


def _trained(models: dict, sources: Sequence[str], flights: Sequence) -> tuple[str, ...]:
    """The names among ``sources`` (one per flight of ``flights``) of the result's training
    flights: by name, or by their data under another name (a copy of a training log)."""
    data = models.get("_trained_data") or frozenset()
    copies = [s for s, f in zip(sources, flights) if data and isinstance(f, Flight) and fingerprint(f) in data]
    return (*models.get("_trained", ()), *copies)


def flight_list(flights) -> list:
    """``flights`` (a Flight or a sequence of them) as a list."""
    return [flights] if isinstance(flights, Flight) else list(flights)


def final_predictions(models: dict, flights: Sequence, ts: float | None = None,
                      method: str | None = None) -> tuple[float, str, object, dict]:
    """(ts, method, fitness, {target: (dataset, predictions, notes)}): each target's rows on ``flights``
    (a :class:`~droneid.dataset.data.Dataset` built with the sampling period ``ts`` (s) and differentiator
    ``method`` the models were identified with unless given) and the v̇ (m/s²) of its models on them:
    {"identified", "empirical", "refit": (n,) arrays} for final models, {"identified"} for a bare
    model file. The data are first checked fit to score (DataError otherwise; ``fitness``: the
    :class:`~droneid.dataset.suitability.Fitness` of that check, None when the models name no signals)."""
    cfg = models.get("_config", {})
    ts = ts or cfg.get("ts") or 0.05
    method = method or cfg.get("method") or "forward"
    builder = DatasetBuilder(ts=ts, method=method)
    flights = flight_list(flights)
    fit = _fitness(models, flights, ts)
    out = {}
    for target, m in models.items():
        if not target.startswith("_"):
            out[target] = (_predict_final(builder, flights, target, m) if "identified" in m
                           else (*_predict_engine(builder, flights, target, m), []))
    return ts, method, fit, out


def predict_flights(models: dict, flights: Sequence, *, ts: float | None = None,
                    method: str | None = None, horizons: Sequence[int] | None = None,
                    open_loop: bool = False) -> Score:
    """Per target and per flight (and all together): samples and the RMSE (m/s²) of the
    identified model, of the empirical model as given and of its refit (:class:`~droneid.use.score.Errors`).

    ``horizons`` (steps): adds the multi-step prediction errors {model: {h: HorizonErrors}} (m/s,
    m; :func:`droneid.simulation.rollout.rollout_errors`, at the log's rate) and ``horizon_info`` (step,
    counts, notes); needs final models. ``open_loop``: adds the open-loop table
    (:func:`open_loop_section`). See :class:`~droneid.use.score.Score`."""
    flights = flight_list(flights)
    sets = model_sets(models)
    if horizons and not sets:
        raise ConfigError("multi-step prediction (--horizons) needs the final models of vx_dot / vy_dot / "
                          "vz_dot (targets.<t>.final in result.json); this result has none")
    ts, method, fit, predicted = final_predictions(models, flights, ts, method)
    results = {}
    for target, (ds, preds, notes) in predicted.items():
        per = {}
        groups = [("all", np.ones(len(ds), bool))]
        if len(ds.sources) > 1:
            groups += [(src, ds.flight == i) for i, src in enumerate(ds.sources)]
        ok = np.logical_and.reduce([np.isfinite(v) for v in preds.values()])
        for name, mask in groups:
            mask = mask & ok
            per[name] = Errors(int(mask.sum()), **{f"rmse_{k}": rmse(v[mask], ds.y[mask]) for k, v in preds.items()})
        if not ok.all():
            notes.append(f"{int((~ok).sum())} of {ok.size} samples left out: a model is not finite there "
                         f"(e.g. a delayed input read before its signal starts)")
        checks = check_constants(models[target].get("constants") or {}, ds.columns(), ds.y, preds["identified"],
                                 ds.t, ds.flight, ds.sources, _trained(models, ds.sources, flights)) \
            if "identified" in preds else ()
        results[target] = TargetScore(models[target].get("equation"), tuple(ds.input_names), tuple(ds.sources), per,
                                      _screened(flights, ds, [*ds.input_names, state_of(target)]),
                                      _out_of_range(ds, models[target].get("input_ranges") or {}), tuple(notes),
                                      models[target].get("use", "identified"), models[target].get("verdict", ""),
                                      checks)
    roll, table, info = None, None, None
    motor = MotorModel.from_record(models.get("_config") or {}) if open_loop else None
    stages = (("horizons",) if horizons else ()) + (("open loop",) if open_loop else ())
    # the multi-step prediction and the open-loop table are independent: side by side on the cores
    done = dict(zip(stages, runner.fork_map(_scoring_stage, (models, sets, tuple(flights), horizons), stages,
                                            runner.default_jobs())))
    if "horizons" in done:
        roll = done["horizons"]
        info = roll.to_dict(segments=False)
        del info["rmse"]
        table = {m: {h: HorizonErrors(**e) for h, e in per.items()} for m, per in roll.rmse.items()}
    return Score(ts, method, results, fit.to_dict() if fit is not None else None,
                 tuple(fit.warnings) if fit is not None else (), table, info, roll, done.get("open loop"),
                 open_loop_rotation=models.get("_rotation") is not None, open_loop_inputs=motor.text() if motor else "")


def _scoring_stage(shared: tuple, stage: str):
    """One of :func:`predict_flights`' scorings of ``shared`` (models, final model sets, flights,
    horizons; :func:`droneid.engine.runner.fork_map`): "horizons", the multi-step prediction
    (:class:`~droneid.simulation.rollout.RolloutResult`), or "open loop", the open-loop table."""
    models, sets, flights, horizons = shared
    if stage == "horizons":
        return rollout_errors(sets, flights, horizons)
    return open_loop_section(models, flights, tuple(horizons or (1, 10, 50)))


def _screened(flights, ds, signals) -> dict:
    """{flight: {signal: implausible samples}} of the signals a target's models read
    (:mod:`droneid.logs.screening`); rows that use them are not scored."""
    out = {}
    for i, f in enumerate(flights):
        counts = implausible_counts(screen_flight(f, signals))
        if counts:
            out[ds.sources[i] if i < len(ds.sources) else f.name] = counts
    return out


#: an input counts as outside the training range beyond this fraction of the range's span
RANGE_MARGIN = 0.05


def _out_of_range(ds, ranges: dict) -> dict:
    """{flight: {input: fraction of the scored samples outside the training range ± 5 % of its
    span}} for inputs that leave it (the model extrapolates there)."""
    out = {}
    for i, src in enumerate(ds.sources):
        sel = ds.flight == i
        if not sel.any():
            continue
        per = {}
        for name, (lo, hi) in ranges.items():
            if name not in ds.input_names:
                continue
            pad = RANGE_MARGIN * max(hi - lo, 1e-12)
            v = ds.X[sel, ds.input_names.index(name)]
            frac = float(np.mean((v < lo - pad) | (v > hi + pad)))
            if frac > 0:
                per[name] = frac
        if per:
            out[src] = per
    return out


def _fitness(models: dict, flights, ts: float):
    """:func:`droneid.dataset.suitability.assess` of the flights for the signals the models read: refuses
    (DataError) data they cannot be scored on (no airborne data, signals far too slow, a
    multirotor model on a fixed-wing log); None when the models name no signals."""
    needed = set()
    for target, m in models.items():
        if target.startswith("_"):
            continue
        needed.add(state_of(target))
        for k in ("identified", "empirical", "refit"):
            if k in m:
                needed |= set(m[k].signals)
        needed |= set(m.get("inputs") or ())
    if not needed:
        return None
    fit = assess(list(flights), needed_signals=sorted(needed), ts=ts, prior_kind="multirotor", inputs_fixed=True)
    fit.raise_if_refused("these logs cannot score the model: ")
    return fit


def _predict_final(builder, flights, target: str, m: dict):
    """Dataset and predictions of the IdentifiedModels of one target. The rows are those identify
    scores: the dataset is built with the final model's input delays (a row whose delayed input
    reaches a screened sample is left out); a model read with other delays (the empirical model,
    the prior refit) re-reads those inputs at ``t − its delay``."""
    ims = {k: m[k] for k in ("identified", "empirical", "refit") if k in m}
    signals = sorted({s for im in ims.values() for s in im.signals})
    main = ims.get("identified")
    delays = dict(main.delays_s) if main is not None else {}
    builder = DatasetBuilder(ts=builder.ts, method=builder.method, delays_s=delays)
    ds = builder.build(flights, target=target, inputs=tuple(signals) or (state_of(target),), extras=())
    cols = ds.columns()
    preds, notes = {}, []
    for name, im in ims.items():
        c = dict(cols)
        for s in im.signals:
            d = float(im.delays_s.get(s, 0.0))
            if s not in c or d == float(delays.get(s, 0.0)):
                continue
            v = np.empty(len(ds))
            for i, f in enumerate(flights):
                sel = ds.flight == i
                v[sel] = sample_inputs(f, [s], ds.t[sel], {s: d})[s]
            c[s] = v
        preds[name] = im.evaluate(c)
        if im.delays_s:
            notes.append(f"{name}: " + ", ".join(f"{s} read at t {'−' if d >= 0 else '+'} {abs(d):g} s"
                                                 for s, d in im.delays_s.items()))
    return ds, preds, notes


def _predict_engine(builder, flights, target: str, m: dict):
    """Dataset and prediction of a bare model file (the engine's model: ``{"identified"}``)."""
    model = SymbolicModel.from_dict(m["model"])
    ds = builder.build(list(flights), target=target, inputs=tuple(m["inputs"]))
    return ds, {"identified": np.asarray(model.predict(ds.columns()), float)}
