"""identify's typed result: per target a :class:`TargetResult` (the ladder, the final model, the
verdict, the coefficients' constancy), the plan it ran under (:class:`PlanRecord`) and the whole
:class:`IdentificationResult`, whose ``to_dict()`` is the ``result.json`` document (schema
:data:`droneid.fitting.closed_form.SCHEMA`, docs/result-json.md) and ``from_dict`` reads it back.
:mod:`droneid.identify.pipeline` composes the stages that make it."""
from __future__ import annotations

import logging
import platform
import sys
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields

from droneid import __version__
from droneid.errors import DataError
from droneid.use.export import export_models, input_sources
from droneid.fitting.closed_form import SCHEMA, IdentifiedModel, check_schema
from droneid.fitting.verdict import model_to_use
from droneid.fitting.constancy import Constancy, SharedConstant
from droneid.core.io_util import to_jsonable
from droneid.identify.ladder import GuardReport, Interval, Rung
from droneid.use.predict import models_from_document, predict_flights
from droneid.use.prediction import PredictionResult, predict_models
from droneid.identify.problem import empirical_model
from droneid.fitting.verdict import verdict
from droneid.rotation.stage import RotationResult
from droneid.use.score import Score
from droneid.identify.search import RunRecord
from droneid.planning.settings import IdentifyConfig

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FeatureText:
    """A prior feature as the result records it: its name, expression (sympy's text, over
    canonical signals), what it means and its role (:data:`priors.base.ROLES`; "" in results
    written before it was recorded)."""
    name: str
    expr: str
    description: str = ""
    role: str = ""

    @classmethod
    def of(cls, d: Mapping) -> "FeatureText":
        """From result.json's ``{"name", "expr", "description", "role"}``."""
        return cls(str(d["name"]), str(d["expr"]), str(d.get("description") or ""), str(d.get("role") or ""))

    @classmethod
    def of_feature(cls, f) -> "FeatureText":
        """From a :class:`priors.base.PriorFeature`."""
        return cls(f.name, str(f.expr), f.description, str(getattr(f, "role", "") or ""))


@dataclass(frozen=True)
class TargetResult:
    """The identification of one target (``result.json``: ``targets.<target>``, docs/result-json.md).

    inputs : the model's inputs; n_train, n_test : rows; test_data : what the test rows are;
        holdout : whether they are a held-out block of the training flights
    constraints : the constraint set the runs trained on (``none``: unconstrained)
    prior_features : what the engine was given; empirical_terms : the prior's terms and effects
    ladder : the rungs, empirical as given -> refit -> offset -> effects -> FINAL (the last)
    guards : what the trust guards did with the runs
    verdict, verdict_kind : one sentence, and its kind (:data:`droneid.fitting.verdict.VERDICT_KINDS`)
    use : the model the verdict says to use: "identified", "empirical" or "neither"
        (:func:`droneid.fitting.verdict.model_to_use`); predict's headline and export follow it
    equation : the final model, readable (prior terms as ⟨name⟩, 4 significant figures)
    identified, empirical, empirical_refit : the errors of the final model, the empirical model as
        given and the prior refit (rmse_train, rmse_test, constraint_rmse_test, ...)
    runs : the SNGP runs (:class:`~droneid.identify.search.RunRecord` summaries); failed_runs : {run: error}
    test_series : t, flight, y and each model's prediction on the test rows; notes : sentences
    intervals : the final model's 95 % intervals; screened : {"training"|"test": {signal: count}}
    input_ranges : {input: (min, max)} over the training rows
    """
    target: str
    inputs: tuple[str, ...]
    n_train: int
    n_test: int
    test_data: str
    holdout: bool
    constraints: str
    prior_features: tuple[FeatureText, ...]
    empirical_terms: tuple[FeatureText, ...]
    ladder: tuple[Rung, ...]
    guards: GuardReport
    verdict: str
    verdict_kind: str
    equation: str
    identified: Mapping[str, object]
    empirical: Mapping[str, object]
    empirical_refit: Mapping[str, object]
    runs: tuple[RunRecord, ...] = ()
    failed_runs: Mapping[str, str] = field(default_factory=dict)
    test_series: Mapping[str, list] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    intervals: Mapping[str, Interval] = field(default_factory=dict)
    screened: Mapping[str, Mapping[str, int]] = field(default_factory=dict)
    input_ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    use: str = ""

    def __post_init__(self):
        object.__setattr__(self, "use", model_to_use(self.verdict_kind, self.use, self.verdict))

    def __repr__(self) -> str:
        return (f"TargetResult({self.target!r}, verdict_kind={self.verdict_kind!r}, n_train={self.n_train}, "
                f"n_test={self.n_test}, equation={self.equation!r})")

    @property
    def final_rung(self) -> Rung:
        return self.ladder[-1]

    @property
    def final(self) -> IdentifiedModel:
        """The final model: what predict applies and export prints."""
        return self.ladder[-1].model

    @property
    def empirical_model(self) -> IdentifiedModel:
        return self.ladder[0].model

    @property
    def refit_model(self) -> IdentifiedModel:
        return self.ladder[1].model

    @property
    def coefficients(self) -> dict:
        """The final model's evolved terms and their coefficients."""
        return {k: v for k, v in self.final_rung.terms.items() if not k.startswith("⟨")}

    @property
    def prior_coefficients(self) -> dict:
        """The final model's scales of the prior's terms and effects (1 = nominal)."""
        return {k.strip("⟨⟩"): v for k, v in self.final_rung.terms.items() if k.startswith("⟨")}

    @property
    def intercept(self) -> float | None:
        return self.final_rung.intercept

    @property
    def constancy(self) -> Mapping[str, Constancy]:
        """The final model's vehicle constants across the training flights (or stretches of one
        flight): :class:`~droneid.fitting.constancy.Constancy` by coefficient (prior terms unbracketed)."""
        return {k.strip("⟨⟩"): v for k, v in self.final_rung.constancy.items()}

    @property
    def chosen_run(self) -> RunRecord | None:
        """The run whose evolved terms are in the final model, or None."""
        i = self.guards.chosen_run
        return self.runs[i] if i is not None and 0 <= i < len(self.runs) else None

    def to_dict(self) -> dict:
        """``targets.<target>`` of result.json."""
        return to_jsonable({
            "target": self.target, "inputs": list(self.inputs), "n_train": self.n_train, "n_test": self.n_test,
            "test_data": self.test_data, "holdout": self.holdout, "constraints": self.constraints,
            "prior_features": [asdict(f) for f in self.prior_features],
            "empirical_terms": [asdict(f) for f in self.empirical_terms],
            "ladder": [r.to_dict() for r in self.ladder], "guards": self.guards.to_dict(),
            "verdict": self.verdict, "verdict_kind": self.verdict_kind, "use": self.use,
            "equation": self.equation, "equation_expanded": f"{self.target} = {self.final.text()}",
            "coefficients": self.coefficients, "prior_coefficients": self.prior_coefficients,
            "intercept": self.intercept, "final": self.final.to_dict(),
            "empirical_model": self.empirical_model.to_dict(), "refit_model": self.refit_model.to_dict(),
            "identified": dict(self.identified), "empirical": dict(self.empirical),
            "empirical_refit": dict(self.empirical_refit), "runs": [r.summary() for r in self.runs],
            "failed_runs": dict(self.failed_runs), "test_series": dict(self.test_series),
            "notes": list(self.notes), "intervals": {k: v.to_list() for k, v in self.intervals.items()},
            "constancy": {k: v.to_dict() for k, v in self.constancy.items()},
            "screened": {k: dict(v) for k, v in self.screened.items()},
            "input_ranges": {k: list(v) for k, v in self.input_ranges.items()}})

    @classmethod
    def from_dict(cls, d: Mapping) -> "TargetResult":
        """Read back :meth:`to_dict` (DataError naming what is missing)."""
        try:
            return cls(
                str(d["target"]), tuple(d["inputs"]), int(d["n_train"]), int(d["n_test"]), str(d["test_data"]),
                bool(d["holdout"]), str(d["constraints"]),
                tuple(FeatureText.of(f) for f in d["prior_features"]),
                tuple(FeatureText.of(f) for f in d["empirical_terms"]),
                tuple(Rung.from_dict(r) for r in d["ladder"]), GuardReport.from_dict(d["guards"]),
                str(d["verdict"]), str(d["verdict_kind"]), str(d["equation"]), dict(d["identified"]),
                dict(d["empirical"]), dict(d["empirical_refit"]),
                tuple(RunRecord.from_dict(r) for r in d["runs"]), dict(d["failed_runs"]),
                dict(d["test_series"]), tuple(d["notes"]),
                {k: Interval.of(v) for k, v in d["intervals"].items()},
                {k: dict(v) for k, v in d["screened"].items()},
                {k: tuple(v) for k, v in d["input_ranges"].items()}, use=str(d.get("use") or ""))
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise DataError(f"not a target result of {SCHEMA}: {type(exc).__name__} {exc}") from None


@dataclass(frozen=True)
class PlanRecord:
    """What the plan and the problem stage decided, as result.json's ``config`` records it next to
    the settings: the prior used (its parameters and why), the validation blocks, the input
    offset with its evidence, the thrust curve of a command-driven vehicle
    (:meth:`droneid.fitting.thrust_curve.ThrustCurve.to_dict`: its shape with interval, the battery
    compensation's test, the values the log declares), the diagnosis, the data fitness per role."""
    prior_used: str = ""
    prior_params: Mapping[str, object] = field(default_factory=dict)
    prior_reason: str = ""
    validation: str = ""
    delays_s: Mapping[str, float] = field(default_factory=dict)
    delay_scores: Mapping[str, float] = field(default_factory=dict)
    offset: Mapping[str, object] | None = None
    thrust_curve: Mapping[str, object] | None = None
    diagnosis: Mapping[str, object] = field(default_factory=dict)
    fitness: Mapping[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class IdentificationResult:
    """What ``droneid identify`` produced: per-target results plus settings, decisions,
    provenance and versions. ``to_dict()`` is result.json; ``from_dict`` reads it back.

    reader_options : the reader options the logs were read with (``--column``, ``--topic``, …):
    predict reads its logs with them by default."""
    targets: Mapping[str, TargetResult]
    config: IdentifyConfig
    plan: PlanRecord
    provenance: Mapping[str, list]
    versions: Mapping[str, str]
    interrupted: bool = False
    wall_s: float = 0.0
    backend: str = ""
    notes: tuple[str, ...] = ()
    horizons: Mapping[str, object] = field(default_factory=dict)   # multi-step prediction on the test flights
    reader_options: Mapping[str, object] = field(default_factory=dict)
    rotation: RotationResult | None = None   # the rotational targets (issue 28); None: not modelled
    #: {role: SharedConstant}: one vehicle constant (the thrust scale) tested across the targets
    shared_constants: Mapping[str, SharedConstant] = field(default_factory=dict)

    def __repr__(self) -> str:
        head = (f"IdentificationResult(targets={list(self.targets)}, prior={self.plan.prior_used!r}, "
                f"runs={self.config.runs}, wall_s={self.wall_s:.1f}{', interrupted' if self.interrupted else ''})")
        return "\n".join([head, *(f"  {t}: {tr.verdict_kind}: {tr.equation}" for t, tr in self.targets.items())])

    def predict(self, flights, *, horizons: Sequence[int] | None = None, ts: float | None = None,
                method: str | None = None) -> PredictionResult:
        """The final models' predictions on ``flights`` (a Flight or a sequence of them).

        Parameters
        ----------
        horizons : steps ahead (at the log's rate) to simulate the states to; None: v̇ only
        ts, method : the grid's period (s) and the measured v̇'s differentiator; None: as identified

        Returns
        -------
        PredictionResult : per target v̇ (m/s²) of each model and as measured on the grid
            (``to_frame()``: a DataFrame with ``t_s``), and with ``horizons`` the simulated states"""
        return predict_models(self._models(), flights, horizons=horizons, ts=ts, method=method)

    def score(self, flights, *, horizons: Sequence[int] | None = None, open_loop: bool = False,
              ts: float | None = None, method: str | None = None) -> Score:
        """The final models' errors on ``flights`` (a Flight or a sequence), as ``droneid predict``.

        Parameters
        ----------
        horizons : steps ahead (at the log's rate) of the multi-step prediction errors; None: none
        open_loop : also the open-loop table (the nanodrone benchmark's metric)
        ts, method : as :meth:`predict`

        Returns
        -------
        Score : per target and flight the RMSE (m/s²) of the final, empirical and refit models"""
        return predict_flights(self._models(), flights, horizons=horizons, open_loop=open_loop, ts=ts, method=method)

    def _models(self) -> dict:   # predict's models of this result
        return models_from_document(self.to_dict(), where="this result")

    def export(self, lang: str = "python", name: str = "droneid_model") -> str:
        """The final (identified) models of every target as source code (``lang``: python, c,
        matlab or latex), whatever the verdicts say; ``droneid export`` writes the model each
        target's verdict says to use (``TargetResult.use``) unless given ``--identified``."""
        return export_models([tr.final for tr in self.targets.values()], lang, source="droneid.Identifier",
                             name=name, inputs=input_sources(self.provenance))

    def to_dict(self) -> dict:
        return to_jsonable({
            "schema": SCHEMA, "targets": {k: v.to_dict() for k, v in self.targets.items()},
            "config": {**self.config.to_dict(), **asdict(self.plan)}, "provenance": dict(self.provenance),
            "versions": dict(self.versions), "interrupted": self.interrupted, "wall_s": self.wall_s,
            "backend": self.backend, "notes": list(self.notes), "horizons": dict(self.horizons),
            "reader_options": dict(self.reader_options),
            "rotation": None if self.rotation is None else self.rotation.to_dict(),
            "shared_constants": {k: v.to_dict() for k, v in self.shared_constants.items()}})

    @classmethod
    def from_dict(cls, d: Mapping) -> "IdentificationResult":
        """Read back result.json; DataError in one line for another schema (a result of version
        1 must be re-made with this version's identify) or a malformed document."""
        if not isinstance(d, Mapping) or "targets" not in d:
            raise DataError("not an identification result (no 'targets')")
        check_schema(d)
        cfg = dict(d.get("config") or {})
        plan = PlanRecord(**{f.name: cfg[f.name] for f in fields(PlanRecord) if f.name in cfg})
        try:
            config = IdentifyConfig.from_dict(cfg)
        except TypeError as exc:
            raise DataError(f"not an identification result: its config: {exc}") from None
        return cls({k: TargetResult.from_dict(v) for k, v in d["targets"].items()}, config, plan,
                   dict(d.get("provenance") or {}), dict(d.get("versions") or {}),
                   bool(d.get("interrupted", False)), float(d.get("wall_s") or 0.0), str(d.get("backend") or ""),
                   tuple(d.get("notes") or ()), dict(d.get("horizons") or {}), dict(d.get("reader_options") or {}),
                   RotationResult.from_dict(d["rotation"]) if d.get("rotation") else None,
                   {str(k): SharedConstant.from_dict(v) for k, v in (d.get("shared_constants") or {}).items()})


def versions() -> dict:
    import numpy
    import scipy
    import sympy
    return {"droneid": __version__, "python": sys.version.split()[0], "numpy": numpy.__version__,
            "scipy": scipy.__version__, "sympy": sympy.__version__, "platform": platform.platform()}


def flight_provenance(flights: Sequence) -> list:
    """Each flight's provenance (files, reader, options) as plain data, with the ``fingerprint`` of
    its data (:func:`droneid.logs.flight.fingerprint`: ``predict`` knows a training flight by it,
    whatever its file is called)."""
    from droneid.logs.flight import Flight, fingerprint
    out = []
    for f in flights:
        p = getattr(f, "provenance", None)
        if p is None:
            continue
        d = asdict(p) if hasattr(p, "__dataclass_fields__") else dict(p)
        out.append({**d, "fingerprint": fingerprint(f)} if isinstance(f, Flight) else d)
    return out

