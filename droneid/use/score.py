"""The error tables of saved models on other logs, typed: what ``droneid predict`` prints and
``IdentificationResult.score`` returns.

A :class:`Score` holds per target a :class:`TargetScore` (its error table, one :class:`Errors` per
flight and ``"all"``), the data-fitness warnings, and, when asked for, the multi-step prediction
table (:class:`HorizonErrors` per model and horizon) and the open-loop table. ``to_dict()`` is the
JSON document of ``droneid predict --json``; :meth:`Score.from_dict` reads it back, from this
version or an older one (which named the refit's error ``rmse_empirical_refit``) the same way.

Errors are RMSEs: of v̇ in m/s², of velocities in m/s, of positions in m. ``None`` means "not
measured" (e.g. a model file without an empirical model); ``nan`` means measured on no sample.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from droneid.core.io_util import to_jsonable

__all__ = ["Errors", "TargetScore", "HorizonErrors", "OpenLoopErrors", "Score"]

#: the refit error's key in predict documents written before the final models existed
_OLD_REFIT = "rmse_empirical_refit"


def _number(v) -> float:
    """A JSON number back as a float (``null``, written for a non-finite one, as nan)."""
    return float("nan") if v is None else float(v)


@dataclass(frozen=True)
class Errors:
    """One row of a target's error table: ``n`` scored samples and the RMSE (m/s²) of the final
    model, of the empirical model as given and of the prior's refit on them (None: not measured)."""
    n: int
    rmse_identified: float
    rmse_empirical: float | None = None
    rmse_refit: float | None = None

    def to_dict(self) -> dict:
        """``{"n", "rmse_identified", ...}``: the errors measured, in this order."""
        return {"n": self.n, **{k: v for k, v in (("rmse_identified", self.rmse_identified),
                                                    ("rmse_empirical", self.rmse_empirical),
                                                    ("rmse_refit", self.rmse_refit)) if v is not None}}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Errors":
        """Read :meth:`to_dict` back; the refit error under either of its names."""
        refit = d["rmse_refit"] if "rmse_refit" in d else d.get(_OLD_REFIT, ...)
        return cls(int(d["n"]), _number(d.get("rmse_identified")),
                   _number(d["rmse_empirical"]) if "rmse_empirical" in d else None,
                   None if refit is ... else _number(refit))


@dataclass(frozen=True)
class TargetScore:
    """One target's score.

    equation : the final model, readable; inputs : the signals its rows were built from;
    sources : the flights (file stems); errors : {"all" | flight: :class:`Errors`} (one row per
    flight only when there are several); screened : {flight: {signal: implausible samples left
    out}}; out_of_range : {flight: {input: fraction of the samples outside the training range}};
    notes : sentences (delayed inputs, samples left out); use, verdict : the model identify's verdict
    says to use ("identified", "empirical" or "neither") and that verdict."""
    equation: str | None
    inputs: tuple[str, ...]
    sources: tuple[str, ...]
    errors: Mapping[str, Errors]
    screened: Mapping[str, Mapping[str, int]] = field(default_factory=dict)
    out_of_range: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    use: str = "identified"
    verdict: str = ""
    #: the result's vehicle constants fitted on each flight alone (:mod:`droneid.use.transfer`)
    constants: tuple = ()

    def to_dict(self) -> dict:
        out = {"equation": self.equation, "inputs": list(self.inputs), "sources": list(self.sources),
               "errors": {k: e.to_dict() for k, e in self.errors.items()},
               "screened": {k: dict(v) for k, v in self.screened.items()},
               "out_of_range": {k: dict(v) for k, v in self.out_of_range.items()}}
        if self.notes:
            out["notes"] = list(self.notes)
        out["use"] = self.use
        if self.verdict:
            out["verdict"] = self.verdict
        if self.constants:
            out["constants"] = [c.to_dict() for c in self.constants]
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> "TargetScore":
        from droneid.use.transfer import ConstantCheck
        return cls(d.get("equation"), tuple(d.get("inputs") or ()), tuple(d.get("sources") or ()),
                   {k: Errors.from_dict(e) for k, e in d["errors"].items()},
                   {k: dict(v) for k, v in (d.get("screened") or {}).items()},
                   {k: dict(v) for k, v in (d.get("out_of_range") or {}).items()}, tuple(d.get("notes") or ()),
                   str(d.get("use") or "identified"), str(d.get("verdict") or ""),
                   tuple(ConstantCheck.from_dict(c) for c in d.get("constants") or ()))


@dataclass(frozen=True)
class HorizonErrors:
    """The multi-step prediction error of one model at one horizon: RMSE of each modelled world
    velocity (m/s) and of the position (m; None where not measured)."""
    vx: float | None = None
    vy: float | None = None
    vz: float | None = None
    position: float | None = None

    def to_dict(self) -> dict:
        return {k: v for k, v in (("vx", self.vx), ("vy", self.vy), ("vz", self.vz),
                                  ("position", self.position)) if v is not None}

    @classmethod
    def from_dict(cls, d: Mapping) -> "HorizonErrors":
        return cls(**{k: _number(d[k]) for k in ("vx", "vy", "vz", "position") if k in d})


@dataclass(frozen=True)
class OpenLoopErrors:
    """One model's open-loop error at one horizon (or SimErr, their sum over 1..50 steps): MAE of
    the position (m), velocity (m/s), attitude (rad) and body rates (rad/s) (:mod:`droneid.simulation.openloop`)."""
    position: float
    velocity: float
    attitude: float
    rates: float

    def to_dict(self) -> dict:
        return {"position": self.position, "velocity": self.velocity, "attitude": self.attitude, "rates": self.rates}

    @classmethod
    def from_dict(cls, d: Mapping) -> "OpenLoopErrors":
        return cls(*(_number(d[k]) for k in ("position", "velocity", "attitude", "rates")))


def _open_loop(table: Mapping | None) -> dict | None:
    """The open-loop table typed: {model: {"1" | … | "simerr": OpenLoopErrors}}."""
    if table is None:
        return None
    return {m: {h: e if isinstance(e, OpenLoopErrors) else OpenLoopErrors.from_dict(e) for h, e in per.items()}
            for m, per in table.items()}


@dataclass(frozen=True)
class Score:
    """What the final models scored on other flights (``droneid predict``).

    ts : sampling period (s) and method : differentiator of the targets (as identified with);
    targets : {target: :class:`TargetScore`}; fitness / warnings : the data-fitness check of the
    logs (:meth:`droneid.dataset.suitability.Fitness.to_dict`; None / () when the models name no
    signals); horizons : {model: {steps: :class:`HorizonErrors`}} of multi-step prediction and
    horizon_info its step ``dt_s`` (s), ``n_starts``, ``skipped`` and notes (None without
    horizons); rollout : the :class:`~droneid.simulation.rollout.RolloutResult` behind them, with its
    traces (for figures; not part of :meth:`to_dict`); open_loop : the open-loop table
    ({model: {"1" | "10" | … steps | "simerr": :class:`OpenLoopErrors`}}, None without it; a
    plain document given here is typed) and open_loop_rotation whether its "identified" row has a
    rotational model (else the rates are held), and open_loop_inputs the motor model its
    command-driven rows are driven through (:meth:`droneid.simulation.motor_model.MotorModel.text`;
    "" for the logged motor speeds); reader_options : {"recorded": the options the
    result was identified with, "given": the options given} (None when neither; set by the CLI).
    """
    ts: float
    method: str
    targets: Mapping[str, TargetScore]
    fitness: Mapping | None = None
    warnings: tuple[str, ...] = ()
    horizons: Mapping[str, Mapping[int, HorizonErrors]] | None = None
    horizon_info: Mapping | None = None
    rollout: object | None = field(default=None, repr=False, compare=False)
    open_loop: Mapping | None = None
    reader_options: Mapping | None = None
    open_loop_rotation: bool = False
    open_loop_inputs: str = ""

    def __post_init__(self):
        object.__setattr__(self, "open_loop", _open_loop(self.open_loop))

    def __repr__(self) -> str:
        lines = [f"Score(ts={self.ts:g} s, method={self.method!r}, targets={list(self.targets)})"]
        for t, s in self.targets.items():
            e = s.errors["all"] if "all" in s.errors else next(iter(s.errors.values()))
            lines.append(f"  {t}: n={e.n}, RMSE final {e.rmse_identified:.4g}"
                         + (f", empirical {e.rmse_empirical:.4g}" if e.rmse_empirical is not None else "")
                         + (f", refit {e.rmse_refit:.4g}" if e.rmse_refit is not None else "") + " m/s²")
        if self.horizons is not None:
            lines.append(f"  horizons (steps): {sorted({h for per in self.horizons.values() for h in per})}")
        if self.open_loop is not None:
            lines.append(f"  open loop: {list(self.open_loop)}")
        return "\n".join(lines)

    def open_loop_table(self) -> dict | None:
        """The open-loop table as plain data ({model: {steps | "simerr": {quantity: MAE}}})."""
        if self.open_loop is None:
            return None
        return {m: {h: e.to_dict() for h, e in per.items()} for m, per in self.open_loop.items()}

    def to_dict(self) -> dict:
        """The JSON document of ``droneid predict --json``."""
        out = {"ts": self.ts, "method": self.method, "targets": {t: s.to_dict() for t, s in self.targets.items()}}
        if self.fitness is not None:
            out["fitness"] = self.fitness
            out["warnings"] = list(self.warnings)
        if self.horizons is not None:
            out["horizons"] = {m: {str(h): e.to_dict() for h, e in per.items()} for m, per in self.horizons.items()}
            out["horizon_info"] = self.horizon_info
        if self.open_loop is not None:
            out["open_loop"] = self.open_loop_table()
            from droneid.simulation.drift import open_loop_verdict
            out["open_loop_verdict"] = open_loop_verdict(out["open_loop"], self.open_loop_rotation)
            out["open_loop_rotation"] = self.open_loop_rotation
            if self.open_loop_inputs:
                out["open_loop_inputs"] = self.open_loop_inputs
        if self.reader_options is not None:
            out["reader_options"] = self.reader_options
        return to_jsonable(out)

    @classmethod
    def from_dict(cls, d: Mapping) -> "Score":
        """Read a ``droneid predict --json`` document back (this version's or an older one's)."""
        horizons = d.get("horizons")
        return cls(float(d["ts"]), str(d["method"]), {t: TargetScore.from_dict(s) for t, s in d["targets"].items()},
                   d.get("fitness"), tuple(d.get("warnings") or ()),
                   None if horizons is None else {m: {int(h): HorizonErrors.from_dict(e) for h, e in per.items()}
                                                  for m, per in horizons.items()},
                   d.get("horizon_info"), None, d.get("open_loop"), d.get("reader_options"),
                   bool(d.get("open_loop_rotation", False)), str(d.get("open_loop_inputs", "")))
