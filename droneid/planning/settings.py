"""The settings of one identification (:class:`IdentifyConfig`), validated once, and the two
budgets (the paper's and a quick look). Recorded in result.json's ``config``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from priors.registry import PRIORS, is_prior_spec
from priors.torque import LAYOUTS

from droneid.errors import ConfigError, check_choice
from droneid.sngp import SNGPRegressor
from droneid.core.targets import TARGETS

__all__ = ["IdentifyConfig", "PAPER_BUDGET", "QUICK_BUDGET", "METHODS", "CONSTRAINT_ALIASES"]

#: the paper's setup per run (Table I); identify makes 4 runs per target by default (the paper: 50;
#: `study` 10): the trust guards decide what survives, and on the shared Crazyflie flights 4 and 10
#: runs give the same final models (measured), in 15 s instead of 43 s
PAPER_BUDGET = {"generations": 60000, "population_size": 500, "runs": 4}
#: a fast look: a few seconds per run on ~200 samples
QUICK_BUDGET = {"generations": 3000, "population_size": 200, "runs": 4}
#: the engine's own defaults (its signature) for what neither budget sets
_ENGINE = SNGPRegressor.default_params()
METHODS = ("forward", "central", "savgol", "spline")
#: ``constraints``: "prior" is the prior's own constraint set, recorded as "paper" (its first name,
#: still accepted: the paper's constraints are the built-in priors' own sets)
CONSTRAINT_ALIASES = {"prior": "paper"}


@dataclass(frozen=True)
class IdentifyConfig:
    """Settings of one identification (all recorded in result.json).

    targets : derivative targets, e.g. ("vx_dot", "vy_dot"); None: every target the prior models
    prior : the physical model the search starts from: "auto" (rotor-thrust where the logs have
        motor speeds, motor commands or thrust, tilt-drag otherwise; the choice and its reason are
        in the result), a built-in name (``priors.registry.PRIORS``) or ``file.toml:name``
    prior_features : 0 (no prior), 1 (the prior as one feature) or 3 (each of its terms, however
        many: 3 for tilt-drag)
    effects : "auto" (diagnose the refit prior on the training flights and fold every effect that
        passes into the prior features) or "none" (the paper's setting)
    delays : "auto" (choose the input delay of the thrust signals by blocked CV on the training
        flights) or "none"
    empirical, k_D : the user's empirical model every comparison is made against ("tilt-drag" as
        given with this k_D, 1/s); v̇z's empirical model is v̇z = 0 (hover balance)
    margin : an evolved model replaces the physical one only if it lowers the blocked-CV error
        of the training flights by this fraction
    search_rows : SNGP searches on at most this many training rows (every k-th, time order kept;
        0: all); the trust guards refit and validate every proposed term on ALL training rows
    constraints : "paper" (the prior's own set; "prior" is read as it), "none" or the path of a
        constraints TOML file
    runs : independent SNGP runs per target; jobs : parallel workers (None: all cores);
    scheduler : a Dask scheduler address (``tcp://host:port``) instead of local workers
    generations, population_size, n_features, max_depth, gamma : SNGP budget (paper: 60000, 500, 10, 7, 0.05)
    n_constraint_samples : samples per constraint for training and (separately) for testing
    seed : root of every random number (run seeds are spawned from ``SeedSequence(seed)``)
    ts, method : dataset sampling period (s) and differentiator
    test_fraction : without test flights: 0 (default) trains on all of the training flights and
        reports validation only; > 0 holds out that last fraction of each flight as test data
        (held out before ANY choice: delay, effects, runs)
    quick : whether the quick budget was asked for (informational; the numbers are above)
    simplify_s : sympy simplification budget per run (s) of the runs' displayed equations (the
        ``runs`` of result.json); 0 (default) keeps the raw terms. It never changes a model: the
        guards and the final model work on the raw terms. It cost 45 % of identify's CPU on the
        shared squares, and what it reaches in its wall-clock budget depends on the load
    prune : "validation" (default: each run searches on 75 % of the training rows and keeps an
        evolved feature only if it lowers the error on the held-out 25 %, then refits on all
        rows; equations stay short and terms fitting noise go) or "exact" (the spec: drop only
        features whose removal changes the training error by < 1e-6; the paper's protocol)
    rotation : "auto" (where the flights log the attitude quaternion, body rates and per-motor
        speeds, also model ω̇x, ω̇y, ω̇z: :mod:`droneid.rotation.stage`) or "none"
    frame : the rotor layout of the rotational model: "auto" (identified from the training
        flights as a torque sign pattern) or a name of ``priors.torque.LAYOUTS``
    """
    targets: tuple[str, ...] | None = None
    prior: str = "auto"
    prior_features: int = 3
    constraints: str = "paper"
    runs: int = PAPER_BUDGET["runs"]
    jobs: int | None = None
    scheduler: str | None = None
    generations: int = PAPER_BUDGET["generations"]
    population_size: int = PAPER_BUDGET["population_size"]
    n_features: int = _ENGINE["n_features"]
    max_depth: int = _ENGINE["max_depth"]
    gamma: float = _ENGINE["gamma"]
    n_constraint_samples: int = 50
    seed: int = 0
    ts: float = 0.05
    method: str = "central"
    test_fraction: float = 0.0
    quick: bool = False
    simplify_s: float = 0.0
    prune: str = "validation"
    effects: str = "auto"
    delays: str = "auto"
    empirical: str = "tilt-drag"
    k_D: float = 0.28
    margin: float = 0.05
    search_rows: int = 1000
    rotation: str = "auto"
    frame: str = "auto"

    @classmethod
    def make(cls, *, quick: bool = False, **given) -> "IdentifyConfig":
        """A validated config; budget items not given come from the quick or the paper budget."""
        budget = QUICK_BUDGET if quick else PAPER_BUDGET
        unknown = set(given) - {f.name for f in fields(cls)}
        if unknown:
            raise ConfigError(f"unknown identify setting(s): {', '.join(sorted(unknown))}")
        given = {k: v for k, v in given.items() if v is not None or k in ("jobs", "scheduler")}
        for k, v in budget.items():
            given.setdefault(k, v)
        if isinstance(given.get("constraints"), str) and given["constraints"] in CONSTRAINT_ALIASES:
            given["constraints"] = CONSTRAINT_ALIASES[given["constraints"]]
        if isinstance(given.get("targets"), str):
            given["targets"] = tuple(s.strip() for s in given["targets"].split(",") if s.strip())
        return cls(quick=quick, **given).validated()

    def validated(self) -> "IdentifyConfig":
        if self.targets is None:
            self._checked()
            return self
        targets = tuple(self.targets)
        if not targets:
            raise ConfigError("The 'targets' parameter must name at least one target. Got none.")
        self._checked()
        for t in targets:
            check_choice("target", t, TARGETS)
        if len(set(targets)) != len(targets):
            raise ConfigError(f"The 'targets' parameter names a target twice: {list(targets)}")
        return replace(self, targets=targets)

    def _checked(self) -> bool:
        """Validate everything but the targets (raises ConfigError); True."""
        check_choice("prior_features", self.prior_features, (0, 1, 3))
        check_choice("effects", self.effects, ("auto", "none"))
        check_choice("delays", self.delays, ("auto", "none"))
        check_choice("rotation", self.rotation, ("auto", "none"))
        check_choice("frame", self.frame, ("auto", *LAYOUTS))
        if not is_prior_spec(self.empirical):
            raise ConfigError(f"The 'empirical' parameter must name a prior (built-in: {', '.join(PRIORS)}; "
                              f"or FILE.toml:NAME). Got {self.empirical!r} instead.")
        if isinstance(self.search_rows, bool) or not isinstance(self.search_rows, (int, np.integer)) \
                or not (self.search_rows == 0 or self.search_rows >= 50):
            raise ConfigError(f"The 'search_rows' parameter must be 0 (all) or an integer >= 50. "
                              f"Got {self.search_rows!r} instead.")
        if not (isinstance(self.margin, (int, float)) and 0 <= self.margin < 0.5):
            raise ConfigError(f"The 'margin' parameter must be in [0, 0.5). Got {self.margin!r} instead.")
        check_choice("method", self.method, METHODS)
        if self.constraints not in ("paper", "none") and not Path(self.constraints).is_file():
            raise ConfigError(f"The 'constraints' parameter must be 'paper', 'none' or an existing "
                              f"TOML file. Got {self.constraints!r} instead (no such file).")
        for name, lo in (("runs", 1), ("n_constraint_samples", 1)):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < lo:
                raise ConfigError(f"The '{name}' parameter must be an integer >= {lo}. Got {v!r} instead.")
        # the engine's parameters: checked by the engine, the one home of their rules
        SNGPRegressor.validate_params(self.engine_params(), owner="identify")
        if self.prior_features > self.n_features:
            raise ConfigError(f"prior_features ({self.prior_features}) cannot exceed n_features "
                              f"({self.n_features}): prior features count toward the {self.n_features}")
        if self.jobs is not None and (not isinstance(self.jobs, int) or self.jobs < 1):
            raise ConfigError(f"The 'jobs' parameter must be a positive integer. Got {self.jobs!r} instead.")
        if not (isinstance(self.ts, (int, float)) and math.isfinite(self.ts) and self.ts > 0):
            raise ConfigError(f"The 'ts' parameter must be a positive number. Got {self.ts!r} instead.")
        if not (self.test_fraction == 0 or 0.05 <= self.test_fraction <= 0.8):
            raise ConfigError(f"The 'test_fraction' parameter must be 0 or in [0.05, 0.8]. "
                              f"Got {self.test_fraction!r} instead.")
        if not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ConfigError(f"The 'seed' parameter must be a non-negative integer. Got {self.seed!r} instead.")
        return True

    @property
    def constrained(self) -> bool:
        return self.constraints != "none"

    def to_dict(self) -> dict:
        """Every setting as JSON-ready data (a prior given as an object: its name)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        if not isinstance(d["prior"], str):
            d["prior"] = getattr(d["prior"], "name", str(d["prior"]))
        if d["targets"] is not None:
            d["targets"] = list(d["targets"])
        return d

    @classmethod
    def from_dict(cls, d: Mapping) -> "IdentifyConfig":
        """The settings back from :meth:`to_dict` (keys it does not know are ignored)."""
        kw = {f.name: d[f.name] for f in fields(cls) if f.name in d}
        if kw.get("targets") is not None:
            kw["targets"] = tuple(kw["targets"])
        return cls(**kw)

    def engine_params(self) -> dict:
        """Keyword arguments of ``SNGPRegressor``: every estimator parameter this config names,
        under the same name (the run's seed is spawned per run, so not this one)."""
        own = {f.name for f in fields(self)}
        return {k: getattr(self, k) for k in SNGPRegressor.param_names() if k in own and k != "seed"}
