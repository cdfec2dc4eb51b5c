"""The settings and the result of a diagnosis (:mod:`droneid.diagnosis.diagnose`), as plain data.

:class:`DiagnoseConfig` (the settings, validated), :class:`DiagnosisResult` (``to_dict()`` is the
``diagnosis.json`` content, ``from_dict`` reads it back), :func:`evidence_of` (the evidence dict of
one decision, reported for every candidate, accepted or rejected), :func:`with_test_errors` (the
test flights' errors attached for the report only) and :func:`fold_into_prior` (a prior plus the
diagnosed effects that can join its features).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import sympy as sp

from priors.registry import PriorFeature, PriorModel

from droneid.fitting.decide import Decision
from droneid.core.differentiation import DIFFERENTIATORS
from droneid.errors import ConfigError, DataError, check_choice
from droneid.core.io_util import to_jsonable

__all__ = ["DiagnoseConfig", "DiagnosisResult", "NO_FURTHER", "evidence_of", "with_test_errors", "held_to_size",
           "folded_feature", "fold_into_prior"]

NO_FURTHER = "no further effect is detectable from these signals"


@dataclass(frozen=True)
class DiagnoseConfig:
    """Settings of a diagnosis (docs/diagnosis.md documents them).

    ts, method: dataset grid step and differentiator (central differences by default: forward
        differences shift the target by Ts/2, which would look like an attitude delay).
    n_blocks: contiguous time blocks per training flight for cross-validation; None (default):
        :func:`diagnose_blocks` (``clip(n_train // 60, 16, 30)``, n_train the training samples
        per target: blocks of ~60 samples, 3 s at 20 Hz).
    alpha: family-wise error level of the decision rule over every candidate the diagnosis may
        try (Holm; :mod:`droneid.fitting.decide`).
    min_rel_improvement: minimum relative CV-RMSE improvement for an effect to count.
    pair_min_gain: when no single effect passes, the best single's relative CV gain from which
        pairs of candidates are tested jointly (overlapping effects); pair_top: how many of the
        best singles form the pairs.
    allow_measured_derivatives: let effects and the open-ended search use measured derivatives
        (IMU ax ay az, differenced vz_dot); the result then says the model cannot be simulated.
    max_steps: most effects added (a joint pair counts as one step).
    ground_h0_m, ground_z_m: decay height (m) of the ground effect and the known ground height (m,
        0: the frame's origin is on the floor or at the take-off point).
    effects: restrict the catalogue to these ids (None: all); user_effects: extra Effect objects.
    generations: budget of the open-ended search per run (0 disables it).
    """
    ts: float = 0.05
    method: str = "central"
    n_blocks: int | None = None
    alpha: float = 0.01
    min_rel_improvement: float = 0.01
    pair_min_gain: float = 0.05
    pair_top: int = 4
    allow_measured_derivatives: bool = False
    max_steps: int = 5
    g: float = 9.81
    ground_h0_m: float = 0.5
    ground_z_m: float = 0.0
    effects: tuple[str, ...] | None = None
    generations: int = 5000
    population_size: int = 500
    n_features: int = 3
    max_depth: int = 5
    seed: int = 0
    max_samples: int = 1500

    def validate(self) -> "DiagnoseConfig":
        if not (self.ts > 0):
            raise ConfigError(f"The 'ts' parameter of DiagnoseConfig must be > 0. Got {self.ts!r} instead.")
        if self.n_blocks is not None and not (isinstance(self.n_blocks, int) and 3 <= self.n_blocks <= 50):
            raise ConfigError("The 'n_blocks' parameter of DiagnoseConfig must be an int in [3, 50]. "
                              f"Got {self.n_blocks!r} instead.")
        if not (0 < self.alpha < 0.5):
            raise ConfigError(f"The 'alpha' parameter of DiagnoseConfig must be in (0, 0.5). Got {self.alpha!r} instead.")
        if not (0 <= self.min_rel_improvement < 1):
            raise ConfigError("The 'min_rel_improvement' parameter of DiagnoseConfig must be in [0, 1). "
                              f"Got {self.min_rel_improvement!r} instead.")
        check_choice("method", self.method, DIFFERENTIATORS, owner="DiagnoseConfig")
        if self.max_steps < 0 or self.generations < 0:
            raise ConfigError("max_steps and generations must be >= 0")
        if not (isinstance(self.pair_top, int) and self.pair_top >= 0):
            raise ConfigError("The 'pair_top' parameter of DiagnoseConfig must be an int >= 0. "
                              f"Got {self.pair_top!r} instead.")
        return self


@dataclass
class DiagnosisResult:
    """The outcome of a diagnosis, as data (``to_dict()`` is the diagnosis.json content).

    targets: {target: {"rmse_prior": {train, test}, "rmse_before": {train, test, cv},
        "rmse_after": {...}, "base_coefficients": {...}, "steps": [...], "open_ended": {...}}}
    steps: the joint steps in order: {"effect", "coefficients", "physical", "rmse": {target:
        {train, test, cv}}, "evidence"}
    effects_added: ids in the order they were added; untestable: {id: "needs ..."};
    not_applicable: {id: why the effect makes no sense for this prior / these targets};
    not_detected: ids tested but not added; conclusion: one sentence.
    final_effects: every added effect in physical terms with the FINAL joint coefficients (a step
        reports the values when it was added; later effects can refine them, e.g. wind after
        quadratic drag), plus ``foldable`` (bool), ``reason`` (why not, else "") and
        ``features``: {target: [{"name": f"{effect}_{param}", "expr": sympy.Expr over canonical
        signals (constants fixed from training), "coefficient": fitted value}]} ({} when not
        foldable). ``to_dict()`` writes the expressions as strings.
    simulable: False when the added effects or a passing open-ended term use a measured
        derivative (only possible with ``allow_measured_derivatives``); notes: such warnings.
    series: per-target arrays for the plots (not in diagnosis.json unless asked for).
    plan: the plan the diagnosis ran under, the one identify makes (:mod:`droneid.planning.plan`):
        ``lines`` (:meth:`droneid.planning.plan.Plan.lines`: the prior and why, the thrust curve, the
        thrust inputs' offset with its test) and :meth:`droneid.planning.plan.Plan.record` ({} when the
        diagnosis was given datasets, not flights).
    """
    targets: dict
    steps: list
    effects_added: list
    untestable: dict
    not_detected: list
    conclusion: str
    open_ended: dict
    config: dict
    prior: str
    sources: dict
    candidates: list = field(default_factory=list)
    final_effects: list = field(default_factory=list)
    not_applicable: dict = field(default_factory=dict)
    simulable: bool = True
    notes: list = field(default_factory=list)
    series: dict = field(default_factory=dict)
    plan: dict = field(default_factory=dict)

    def to_dict(self, include_series: bool = False) -> dict:
        d = {"targets": self.targets, "effects_added": self.effects_added,
             "untestable": sorted(self.untestable), "untestable_reasons": self.untestable,
             "not_detected": self.not_detected, "conclusion": self.conclusion,
             "steps": self.steps, "final_effects": [_final_effect_json(fe) for fe in self.final_effects],
             "open_ended": self.open_ended, "candidates": self.candidates,
             "not_applicable": self.not_applicable, "simulable": self.simulable,
             "notes": self.notes, "plan": self.plan,
             "prior": self.prior, "config": self.config, "sources": self.sources}
        if include_series:
            d["series"] = self.series
        return to_jsonable(d)

    @classmethod
    def from_dict(cls, d: Mapping) -> "DiagnosisResult":
        """The result back from :meth:`to_dict` (``diagnosis.json``): feature expressions stay
        text; without ``series`` (not saved by default) the report has no time-series figures.
        DataError for a document that is not a diagnosis."""
        if not isinstance(d, Mapping) or not isinstance(d.get("targets"), Mapping) \
                or "effects_added" not in d:
            raise DataError("not a diagnosis result (it needs 'targets' and 'effects_added')")
        sources = d.get("sources") or {}
        return cls(targets=dict(d["targets"]), steps=list(d.get("steps") or []),
                   effects_added=list(d["effects_added"] or []),
                   untestable=dict(d.get("untestable_reasons") or {}),
                   not_detected=list(d.get("not_detected") or []), conclusion=str(d.get("conclusion") or ""),
                   open_ended=dict(d.get("open_ended") or {}), config=dict(d.get("config") or {}),
                   prior=str(d.get("prior") or ""),
                   sources={"train": list(sources.get("train") or []), "test": list(sources.get("test") or [])},
                   candidates=list(d.get("candidates") or []), final_effects=list(d.get("final_effects") or []),
                   not_applicable=dict(d.get("not_applicable") or {}), simulable=bool(d.get("simulable", True)),
                   notes=list(d.get("notes") or []), series=dict(d.get("series") or {}),
                   plan=dict(d.get("plan") or {}))


def _final_effect_json(fe: dict) -> dict:
    """A final effect with its feature expressions as strings."""
    return {**fe, "features": {t: [{**f, "expr": str(f["expr"])} for f in fs]
                               for t, fs in fe.get("features", {}).items()}}


def evidence_of(dec: Decision) -> dict:
    """The evidence dict of a diagnosis decision (reported for every candidate, accepted or
    rejected) from a :class:`droneid.fitting.decide.Decision`."""
    return {"cv_rmse_before": dec.rmse_without, "cv_rmse_after": dec.rmse_with,
            "rel_improvement": dec.effect_pct / 100.0, "p_value": dec.p_value,
            "p_threshold": dec.threshold, "statistic": dec.statistic, "n_blocks": dec.n_blocks,
            "n_candidates": dec.family_size, "holm_rank": dec.rank,
            "blocks_improved": f"{dec.blocks_better}/{dec.n_blocks}",
            "block_rel_improvements": list(dec.block_differences), "passed": dec.accepted,
            "reasons": list(dec.reasons), "text": dec.evidence}


def with_test_errors(ev: dict, test_before: float | None, test_after: float | None) -> dict:
    """``ev`` plus the test flights' RMSE before/after, REPORTED only (never part of passing)."""
    rel = (1.0 - test_after / test_before if test_before else 0.0) \
        if test_before is not None and test_after is not None else None
    return {**ev, "test_rmse_before": test_before, "test_rmse_after": test_after,
            "test_rel_improvement": rel}


def held_to_size(ev: dict, interp, floor: float) -> dict:
    """``ev`` of an effect judged on its own rows, rejected when its physical size
    (``interp.size``, a fraction) is under the rule's size floor ``floor``: the relative drop of
    such residuals measures nothing physical (docstring of priors/effect_catalogue/motor_thrust)."""
    if interp.size is None or interp.size >= floor:
        return ev
    why = f"{interp.size_what or 'its size is'} {100 * interp.size:.2g} % (< {100 * floor:g} %)"
    text = ev["text"].replace(": accepted", f": rejected ({why})") if ev["passed"] else \
        ev["text"][:-1] + f"; {why})" if ev["text"].endswith(")") else ev["text"]
    return {**ev, "passed": False, "reasons": [*ev["reasons"], why], "text": text}


def folded_feature(effect: str, feature: Mapping, physical: str = "") -> PriorFeature:
    """One feature of a diagnosed effect as it joins the model, with only the sign and size the
    effect's own test supports (one home for identify's plan and :func:`fold_into_prior`):

    - an effect judged on its own rows (``assess_fn``: per-motor thrust, from the motors' thrust
      shares) is folded as its test measured it, its coefficient FIXED at 1 (the k_i of its
      test); the v̇ data cannot see it (a free refit would let it absorb noise with any sign);
    - an effect judged on the v̇ residual is folded as its diagnosed term, ``coefficient ·
      expr``, with a scale bounded to [0, ∞) (1 = as diagnosed): a refit may shrink it or, where
      the data cannot pin it, hold it at 1, but never turn its sign.

    ``feature``: ``{name, expr, coefficient}`` of ``final_effects[i]["features"][target]``."""
    from priors.effects import CATALOGUE
    eff = CATALOGUE.get(effect)
    desc = f"diagnosed effect {effect}: {physical}"
    c = float(feature["coefficient"]) if feature.get("coefficient") is not None else float("nan")
    if eff is not None and eff.assess_fn is not None:
        return PriorFeature(feature["name"], feature["expr"], desc, "other", limits=(1.0, 1.0))
    if not (c == c) or c == 0.0:   # no usable diagnosed value: a free coefficient
        return PriorFeature(feature["name"], feature["expr"], desc, "other")
    return PriorFeature(feature["name"], sp.Float(c) * feature["expr"], desc, "other", limits=(0.0, float("inf")))


def fold_into_prior(result: DiagnosisResult, prior):
    """A new :class:`priors.registry.PriorModel`: ``prior`` plus every foldable final effect's
    features (:func:`folded_feature`: role ``"other"``, description naming the effect), with
    the signals they use added to the prior's inputs. Effects that are not foldable (per-flight
    conditions, attitude delay, measured derivatives) are left out. Raises ConfigError when the
    prior is not a PriorModel."""
    if not isinstance(prior, PriorModel):
        raise ConfigError(f"fold_into_prior needs a PriorModel, got {type(prior).__name__}")
    terms = {t: list(prior.features(t)) for t in prior.targets}
    inputs = {t: list(prior.inputs(t)) for t in prior.targets}
    for fe in result.final_effects:
        if not fe.get("foldable"):
            continue
        for t, feats in fe["features"].items():
            if t not in terms:
                continue
            for f in feats:
                feat = folded_feature(fe["effect"], f, fe["physical"])
                terms[t].append(feat)
                inputs[t].extend(sorted(s.name for s in feat.expr.free_symbols if s.name not in inputs[t]))
    added = [fe["effect"] for fe in result.final_effects if fe.get("foldable")]
    if not added:
        return prior
    return PriorModel(f"{prior.name}+{'+'.join(added)}",
                      f"{prior.description} Plus the diagnosed effects {', '.join(added)}.",
                      terms, inputs, dict(prior.params), vehicle=prior.vehicle,
                      constraints=prior.constraints, intercept=dict(prior.intercept))

