"""The catalogue of candidate effects the diagnosis tests against a model's residual.

Each :class:`Effect` is a physical effect the prior leaves out, written as columns that enter the
model LINEARLY in unknown coefficients, so adding an effect is one least-squares refit:

    v̇_axis = prior terms (refit) + Σ_p  coef_p · feature_p(signals)

Every effect states

* ``id`` and ``description``;
* ``needs``: the signals it needs, as groups of alternatives (each group needs ONE available signal);
  ``"@tilt"`` means "the prior has thrust-direction terms for the target". An effect whose needs
  are not met is UNTESTABLE (never "absent");
* ``data_fn(ctx) -> reason or None``: its PRECONDITIONS, checked on the training data (e.g.
  ground effect needs time near the ground at a known height; attitude bias needs yaw
  variation to be told from wind; quadratic drag needs speed): when one fails the effect is
  UNTESTABLE with that reason and is never tried (a candidate that the data cannot identify
  can only stand in for something else);
* ``targets``: the targets it applies to (horizontal-only effects skip ``vz_dot``) and
  ``not_applicable(ctx)``: a reason when it makes no sense with this prior (e.g. thrust_variation
  when the prior's thrust is logged already);
* ``constants(ctx) -> {name: float}``: numbers fixed from the TRAINING data (mean thrust, mean
  voltage, ground height); the same numbers are used on test flights and in the folded model;
* ``expressions(ctx, constants) -> {param: sympy.Expr}`` (foldable effects): the features as
  sympy expressions over canonical signal symbols with every constant a number; the numeric
  features ``features(ctx, constants)`` are these expressions evaluated on the data, so folding an
  effect into a model reproduces the fit exactly. Non-foldable effects (``foldable`` False, with
  ``fold_reason``) compute columns directly: per-flight conditions (wind, attitude bias) and
  effects that need a time derivative (attitude delay). A parameter name used for several
  targets is ONE coefficient shared by them (e.g. the quadratic-drag ``c``); axis-specific names
  (``offset_x``) are separate coefficients;
* ``interpret(coef, base) -> Interpretation``: the fitted coefficients in physical terms;
* ``per_flight``: a condition of the flight rather than of the vehicle (wind, attitude bias): its
  parameters are estimated separately for every flight; on a test flight they are estimated by
  blocked cross-validation on that flight, with everything else fixed from training;
* ``refine(ctx, coef, base) -> {column: array}`` (optional ``refine_fn``): an effect may refine
  itself after a fit. The diagnosis calls it after every fit that includes the effect, for every
  target's context on the training and the test flights, with the effect's fitted coefficients
  per flight and the base model's linear drag ``k_D`` (1/s); the columns it returns are set in the
  context and the model is refitted (twice: a fixed point). The wind uses it to set the air
  velocity ``vx_air``, ``vy_air``, ``speed_air`` (m/s) that drag effects then act on;
* ``order``: where a built-in effect stands in the catalogue (the order the diagnosis tries them).

Causal inputs only: effects are built from states and inputs (velocity, attitude, height, logged
thrust / motor signals, battery voltage), never from a measured derivative (``vz_dot`` from
differencing, IMU ``ax ay az``). Those columns exist in an :class:`EffectContext` only when it is
built with ``allow_measured_derivatives=True``; a model using them cannot be simulated.

Conventions (droneid frames: world ENU, Z-Y-X Euler, positive pitch = nose down). ``G`` is the
prior's thrust-direction term for the target at the scale of the base refit on the training
flights (Σ β_term · term): the sum of its terms with role ``tilt``
(tilt-drag: ``G_x = g cosψ tanθ/cosφ + g sinψ tanφ``) or ``thrust`` (rotor-thrust: logged thrust
along body z), or for priors without roles the terms containing roll or pitch. ``k_D`` is the
fitted linear drag coefficient of the base model in 1/s (from the role ``drag`` terms).

The built-in effects (:data:`CATALOGUE`) are the modules of :mod:`priors.effect_catalogue`, one
per effect, each exporting ``EFFECT = Effect(...)`` and documenting its features and their
physical reading in its docstring; they are found on first use and ordered by ``Effect.order``.
Adding one is one new module there (docs/extending.md).

User effects: :func:`load_effects` reads TOML (see docs/diagnosis.md); expressions are
parsed only with :func:`droneid.core.expressions.parse_expression`.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import sympy as sp

from droneid.core.io_util import load_toml
from droneid.errors import ConfigError, did_you_mean
from droneid.core.expressions import compile_expression, parse_expression, safe_format, symbol
from droneid.logs.flight import CANONICAL_SIGNALS
from droneid.core.plugins import public_modules
from droneid.core.targets import HORIZONTAL, TARGETS, axis_of, velocity_of

from .effect_signals import high, spread, time_derivative
from .thrust import RPM_SCALE, motor_count

__all__ = [
    "Effect", "EffectContext", "Interpretation", "CATALOGUE", "TILT", "get_effect",
    "load_effects", "time_derivative", "MEASURED_DERIVATIVES",
    "is_measured_derivative", "thrust_proxy", "mean_k_drag", "PER_FLIGHT_REASON", "clear_cache",
    "spread", "high", "must_be_positive",
]

#: Pseudo-signal meaning "the prior has thrust-direction terms for this target".
TILT = "@tilt"
#: Signals that are a measured derivative of the modelled velocity (never causal inputs).
MEASURED_DERIVATIVES = ("ax", "ay", "az", *TARGETS)
#: Names user expressions may use besides canonical signals.
DERIVED = {
    "G": "the prior's thrust-direction terms for the target, m/s²",
    "vz_dot": "vertical acceleration from vz (central differences), m/s² (a measured derivative: "
              "needs allow_measured_derivatives)",
    "speed": "horizontal speed sqrt(vx² + vy²), m/s",
    "v_axis": "the target's own velocity (vx for vx_dot, vy for vy_dot, vz for vz_dot), m/s",
}


def is_measured_derivative(name: str) -> bool:
    """True for IMU accelerations and differenced velocities (``ax``, ``vz_dot``, ``*_dot``)."""
    return name in MEASURED_DERIVATIVES or name.endswith("_dot")


@dataclass(frozen=True)
class EffectContext:
    """What an effect may read for ONE target: columns on the grid and the prior's G terms.

    ``columns`` holds the Dataset's inputs and extras (canonical names) plus derived columns
    (``speed``, ``v_axis``, ``G`` where computable, and ``vz_dot`` only with
    ``allow_measured_derivatives``; measured derivatives ``ax ay az *_dot`` are dropped otherwise).
    ``tilt`` is the prior's G expression (sympy over canonical symbols) or None; ``tilt_role`` is
    ``"tilt"`` (thrust direction at hover balance) or ``"thrust"`` (logged thrust); ``options``
    holds effect options (``ground_h0_m``, ``ground_z_m``, ``derivative_half_window_s``).
    """
    target: str
    columns: Mapping[str, np.ndarray]
    t: np.ndarray
    flight: np.ndarray
    tilt: sp.Expr | None = None
    g: float = 9.81
    options: Mapping[str, float] = field(default_factory=dict)
    tilt_role: str = "tilt"
    allow_measured_derivatives: bool = False

    @classmethod
    def build(cls, target: str, columns: Mapping[str, np.ndarray], t, flight, tilt=None,
              g: float = 9.81, options: Mapping[str, float] | None = None, tilt_role: str = "tilt",
              allow_measured_derivatives: bool = False) -> "EffectContext":
        cols = {k: np.asarray(v, float) for k, v in columns.items()
                if k not in (target, "t") and np.all(np.isfinite(np.asarray(v, float)))
                and (allow_measured_derivatives or not is_measured_derivative(k))}
        t = np.asarray(t, float)
        flight = np.asarray(flight, int)
        if "vz" in cols and allow_measured_derivatives:
            cols["vz_dot"] = time_derivative(cols["vz"], t, flight)
        if "vx" in cols and "vy" in cols:
            cols["speed"] = np.hypot(cols["vx"], cols["vy"])
        vel = velocity_of(target)
        if vel in cols:
            cols["v_axis"] = cols[vel]
        ctx = cls(target, cols, t, flight, tilt, g, dict(options or {}), tilt_role,
                  allow_measured_derivatives)
        if tilt is not None and ctx._can_eval(tilt):
            cols["G"] = ctx.evaluate(tilt)
        return ctx

    @property
    def axis(self) -> str | None:
        return axis_of(self.target)

    def with_columns(self, columns: Mapping[str, np.ndarray]) -> "EffectContext":
        """A copy with ``columns`` added (or replacing columns of the same name)."""
        return replace(self, columns={**self.columns, **columns})

    def available(self) -> set[str]:
        """Names of usable columns, plus ``"@tilt"`` when the prior's G terms are computable."""
        names = set(self.columns)
        if "G" in self.columns:
            names.add(TILT)
        return names

    def _can_eval(self, expr) -> bool:
        return all(s.name in self.columns for s in expr.free_symbols)

    def evaluate(self, expr: sp.Expr, air: bool = False) -> np.ndarray:
        """``expr`` on the columns; ``air``: velocities vx, vy read as the air velocity
        (``vx_air``, ``vy_air``) where a wind estimate set them."""
        names = sorted(s.name for s in expr.free_symbols)
        f = compile_expression(expr, names)
        n = self.t.size

        def col(k):
            return self.columns.get(f"{k}_air", self.columns[k]) if air and k in ("vx", "vy") \
                else self.columns[k]
        return np.broadcast_to(f({k: col(k) for k in names} or {"_": np.zeros(n)}),
                               (n,)).astype(float)

    def tilt_partial(self, signal: str) -> np.ndarray:
        """∂G/∂signal evaluated on the data (zero if G does not depend on it)."""
        return self.evaluate(sp.diff(self.tilt, symbol(signal)))

    def d_dt(self, x: np.ndarray) -> np.ndarray:
        """Smoothed d/dt (half window ``options['derivative_half_window_s']``, default 0.1 s)."""
        return time_derivative(x, self.t, self.flight,
                               float(self.options.get("derivative_half_window_s", 0.1)))


@dataclass(frozen=True)
class Interpretation:
    """Fitted coefficients of one effect in physical terms: a sentence and named values.

    ``size``: for an effect judged on its own rows (``assess_fn``), its physical size as a fraction
    (per-motor thrust: the largest ``|r_i − 1|``), held to the rule's size floor
    (``DiagnoseConfig.min_rel_improvement``) where the relative drop of its residuals has no
    meaning; ``size_what`` names it for the evidence line. None: no such size."""
    text: str
    values: dict
    size: float | None = None
    size_what: str = ""


@dataclass(frozen=True)
class Effect:
    """One candidate effect (see the module docstring).

    Exactly one of ``expr_fn(ctx, constants) -> {param: sympy.Expr}`` (foldable effects) and
    ``column_fn(ctx, constants) -> {param: column}`` computes the features;
    ``constants_fn(ctx) -> {name: float}`` fixes numbers from the training data;
    ``applicable_fn(ctx) -> reason or None`` says when the effect makes no sense for the prior;
    ``data_fn(ctx) -> reason or None`` when the (training) data cannot identify it;
    ``refine_fn(ctx, coef, base) -> {column: array}`` refines the effect after a fit (see
    :meth:`refine`); ``assess_fn(ctx, blocks) -> (err_without, err_with, row_blocks,
    Interpretation)``: an effect judged on other rows than the v̇ residual (per-motor thrust: the
    motors' thrust shares), by the same decision rule; ``plausible_fn(values) -> reason or None``:
    whether the fitted physical values (``Interpretation.values``) are physically possible (a
    negative drag, a rotor radius of metres, thrust ∝ ω^0.7, an attitude that leads the
    acceleration): an effect that only fits with impossible values is a stand-in for something
    else and is rejected with that reason; ``order``: its place in the catalogue (built-in effects; the diagnosis tries
    effects in increasing order, ties by id).
    """
    id: str
    description: str
    needs: tuple[tuple[str, ...], ...]
    interpret_fn: Callable[[dict, dict], Interpretation]
    expr_fn: Callable[[EffectContext, dict], dict] | None = None
    column_fn: Callable[[EffectContext, dict], dict] | None = None
    constants_fn: Callable[[EffectContext], dict] | None = None
    applicable_fn: Callable[[EffectContext], str | None] | None = None
    data_fn: Callable[[EffectContext], str | None] | None = None
    targets: tuple[str, ...] = HORIZONTAL
    explain_signal: str = ""
    user: bool = False
    per_flight: bool = False
    fold_reason: str = ""
    refine_fn: Callable[[EffectContext, dict, dict], Mapping[str, np.ndarray]] | None = None
    order: int = 0
    assess_fn: Callable[[EffectContext, np.ndarray], tuple] | None = None
    plausible_fn: Callable[[dict], str | None] | None = None

    @property
    def foldable(self) -> bool:
        """True when the effect is an instantaneous function of states and inputs with constants
        fixed from training (it can join the model's features); see ``fold_reason`` otherwise."""
        return self.expr_fn is not None and not self.per_flight and not self.fold_reason

    def missing(self, available: Iterable[str]) -> list[str]:
        """Unmet needs, each as 'a|b' alternatives; empty when testable."""
        avail = set(available)
        return ["|".join(_need_label(a) for a in grp) for grp in self.needs
                if not any(a in avail for a in grp)]

    def applies_to(self, target: str) -> bool:
        return target in self.targets

    def not_applicable(self, ctx: EffectContext) -> str | None:
        """Why the effect makes no sense for ctx's target and prior (None: it applies)."""
        if not self.applies_to(ctx.target):
            return f"does not apply to {ctx.target}"
        return self.applicable_fn(ctx) if self.applicable_fn else None

    def untestable_data(self, ctx: EffectContext) -> str | None:
        """Why these (training) data cannot identify the effect although its signals exist."""
        return self.data_fn(ctx) if self.data_fn else None

    def constants(self, ctx: EffectContext) -> dict:
        """Numbers fixed from ``ctx`` (the TRAINING data): {} when the effect has none or when
        it is untestable or not applicable there."""
        if self.constants_fn is None or self.missing(ctx.available()) or self.not_applicable(ctx):
            return {}
        return {k: float(v) for k, v in self.constants_fn(ctx).items()}

    def expressions(self, ctx: EffectContext, constants: Mapping[str, float] | None = None
                    ) -> dict[str, sp.Expr]:
        """``{param: sympy.Expr}`` over canonical signal symbols for ctx's target (G and the
        constants substituted by numbers); {} when not foldable, untestable or not applicable.
        ``constants`` default: :meth:`constants` of ``ctx`` (pass the training ones for test data)."""
        if self.expr_fn is None or self.missing(ctx.available()) or self.not_applicable(ctx):
            return {}
        consts = self.constants(ctx) if constants is None else dict(constants)
        return dict(self.expr_fn(ctx, consts) or {})

    def features(self, ctx: EffectContext, constants: Mapping[str, float] | None = None
                 ) -> dict[str, np.ndarray]:
        """``{param: column}`` for ctx's target, or ``{}`` when it does not apply there.
        Foldable effects evaluate :meth:`expressions` (drag effects on the air velocity when a
        wind estimate is set); non-finite values become 0."""
        if self.missing(ctx.available()) or self.not_applicable(ctx):
            return {}
        consts = self.constants(ctx) if constants is None else dict(constants)
        if self.expr_fn is not None:
            cols = {k: ctx.evaluate(e, air=True) for k, e in self.expressions(ctx, consts).items()}
        else:
            cols = self.column_fn(ctx, consts) or {}
        n = ctx.t.size
        out = {}
        for k, v in cols.items():
            v = np.broadcast_to(np.asarray(v, float), (n,)).copy()
            v[~np.isfinite(v)] = 0.0
            out[k] = v
        return out

    def implausible(self, values: Mapping[str, float]) -> str | None:
        """Why fitted physical ``values`` are impossible (None: plausible, or no check)."""
        return self.plausible_fn(dict(values)) if self.plausible_fn else None

    def assess(self, ctx: EffectContext, blocks: np.ndarray) -> tuple:
        """``(err_without, err_with, row_blocks, Interpretation)`` from ``assess_fn`` on the
        TRAINING context ``ctx`` with its validation ``blocks`` (ConfigError without one)."""
        if self.assess_fn is None:
            raise ConfigError(f"effect '{self.id}' is judged on the v̇ residual (no assess_fn)")
        return self.assess_fn(ctx, np.asarray(blocks))

    def interpret(self, coef: Mapping[str, float], base: Mapping) -> Interpretation:
        """Physical terms from ``coef`` ({param: value}) and ``base`` info (``k_D``: {target: k})."""
        return self.interpret_fn(dict(coef), dict(base))

    def refine(self, ctx: EffectContext, coef: Mapping[int, Mapping[str, float]], base: Mapping
               ) -> dict[str, np.ndarray]:
        """Columns to set in ``ctx`` after a fit that includes the effect ({} without ``refine_fn``).

        ``ctx``: one target's context on the training or the test flights (every target's, whether
        or not the effect applies to it); ``coef``: {flight code as in ``ctx.flight``: {param:
        fitted value}} for every flight of ``ctx`` (a per-flight effect's own values, else the
        shared ones; {} for a flight without them), in the units of the effect's coefficients;
        ``base``: base-model info, ``k_D``: {target: fitted linear drag in 1/s or None}.
        Returns {column name: array on ctx's grid} (e.g. the wind's ``vx_air`` in m/s); drag-type
        effects read ``vx_air``, ``vy_air`` through ``EffectContext.evaluate(..., air=True)``.
        """
        if self.refine_fn is None:
            return {}
        n = ctx.t.size
        return {k: np.broadcast_to(np.asarray(v, float), (n,)).copy()
                for k, v in (self.refine_fn(ctx, {int(f): dict(c) for f, c in coef.items()},
                                            dict(base)) or {}).items()}


def must_be_positive(value: float, what: str) -> str | None:
    """A ``plausible_fn`` reason when a fitted drag-like ``value`` is not > 0 (``what`` names it
    with its unit placeholder, e.g. "quadratic drag c_D/m = {:.3g} 1/m"); None when positive."""
    return None if value > 0 else f"the fitted {what.format(value)} is not positive"


def _need_label(name: str) -> str:
    return "thrust-direction (tilt or thrust) terms of the prior" if name == TILT else name


# -- the catalogue ------------------------------------------------------------------------------
#: The reason a per-flight effect is not foldable (built-in and user effects).
PER_FLIGHT_REASON = "a condition of one flight (estimated per flight), not of the vehicle"
#: The package whose modules are the built-in effects.
_CATALOGUE_PACKAGE = "priors.effect_catalogue"
_CACHE: dict[str, Effect] | None = None


def mean_k_drag(base: Mapping) -> float:
    """Mean fitted linear drag k_D (1/s) of the horizontal targets in ``base`` (``k_D``:
    {target: k}); NaN without a finite one."""
    ks = [k for t, k in (base.get("k_D") or {}).items()
          if t in HORIZONTAL and k is not None and math.isfinite(k)]
    return float(np.mean(ks)) if ks else float("nan")


def thrust_proxy(available: Iterable[str]) -> tuple[str, sp.Expr] | None:
    """(description, sympy expression) of the logged quantity most nearly proportional to the
    collective thrust, or None: ``thrust`` (N), else Σ(rpm_i/10⁴)² (rotor momentum theory),
    else the mean motor command, else ``throttle``."""
    have = set(available)
    if "thrust" in have:
        return "thrust", symbol("thrust")
    counts = motor_count(have)
    for src, label in (("rpm", "Σ(rpm/10⁴)²"), ("motor", "mean motor command")):
        n = counts.get(src, 0)
        if n:
            if src == "rpm":
                return label, sp.Add(*[(symbol(f"rpm{i}") / int(RPM_SCALE)) ** 2 for i in range(1, n + 1)])
            return label, sp.Add(*[symbol(f"motor{i}") for i in range(1, n + 1)]) / n
    if "throttle" in have:
        return "throttle", symbol("throttle")
    return None


def _discover() -> dict[str, Effect]:
    """{id: Effect} from every public module of :mod:`priors.effect_catalogue` (each exports
    ``EFFECT`` and is named after its id, so ids are unique), in increasing ``order``, ties
    by id."""
    found: list[Effect] = []
    for mod in public_modules(_CATALOGUE_PACKAGE):
        name = mod.__name__.rsplit(".", 1)[-1]
        here = getattr(mod, "__file__", name)
        eff = getattr(mod, "EFFECT", None)
        if not isinstance(eff, Effect):
            got = "no EFFECT" if eff is None else f"EFFECT of type {type(eff).__name__}"
            raise ConfigError(f"{here}: a module of {_CATALOGUE_PACKAGE} must export EFFECT = "
                              f"Effect(...); got {got} instead (helper modules start with '_')")
        if eff.id != name:
            raise ConfigError(f"{here}: exports effect '{eff.id}'; name the module after its id "
                              f"({eff.id}.py)")
        found.append(eff)
    return {e.id: e for e in sorted(found, key=lambda e: (e.order, e.id))}


def _discovered() -> dict[str, Effect]:
    global _CACHE
    if _CACHE is None:
        _CACHE = _discover()
    return _CACHE


def clear_cache() -> None:
    """Forget the discovered built-in effects (tests that add a plug-in module call this)."""
    global _CACHE
    _CACHE = None


class _Catalogue(Mapping):
    """The built-in effects, id -> :class:`Effect` (read-only, in the order the diagnosis tries
    them): the modules of :mod:`priors.effect_catalogue`, discovered on first use."""

    def __getitem__(self, effect_id: str) -> Effect:
        return _discovered()[effect_id]

    def __iter__(self):
        return iter(_discovered())

    def __len__(self) -> int:
        return len(_discovered())

    def __repr__(self) -> str:
        return f"CATALOGUE({', '.join(self)})"


#: The built-in effects by id, in the order the diagnosis tries them (discovered on first use).
CATALOGUE: Mapping[str, Effect] = _Catalogue()


def get_effect(effect_id: str, effects: Mapping[str, Effect] | None = None) -> Effect:
    """The effect ``effect_id`` of ``effects`` (default: the built-in catalogue); ConfigError
    with the nearest id for an unknown one."""
    effects = CATALOGUE if effects is None else effects
    try:
        return effects[effect_id]
    except KeyError:
        raise ConfigError(f"unknown effect '{effect_id}'{did_you_mean(effect_id, effects)}; "
                          f"known: {', '.join(effects)}") from None


# -- user effects from TOML ---------------------------------------------------------------------
_EXPR_NAMES = (*CANONICAL_SIGNALS, *(f"motor{i}" for i in range(1, 17)), *DERIVED)
_DERIVED_NEEDS = {"G": ((TILT,),), "vz_dot": (("vz_dot",),), "speed": (("vx",), ("vy",)),
                  "v_axis": (("vx", "vy", "vz"),)}


def load_effects(path) -> dict[str, Effect]:
    """User effects from a TOML file; raises :class:`ConfigError` on anything wrong.

    Format (one ``[[effect]]`` table per effect)::

        [[effect]]
        id = "rotor_drag"
        description = "blade flapping drag"
        meaning = "rotor drag k = {k:.3g} 1/s"      # str.format over the parameter names
        per_flight = false                          # true: one value per flight (like wind)
        [effect.features.vx_dot]
        k = "-vx * cos(yaw)**2"                     # parameter name = expression
        [effect.features.vy_dot]
        k = "-vy * sin(yaw)**2"

    A parameter name used under several targets is one shared coefficient. Expressions may use
    canonical signals, ``g`` and the derived names ``G``, ``vz_dot``, ``speed``, ``v_axis``.
    """
    p = Path(path)
    data = load_toml(p, "effects file")
    unknown = set(data) - {"effect"}
    if unknown:
        raise ConfigError(f"{p}: unknown top-level key(s) {sorted(unknown)}; expected [[effect]] tables")
    tables = data.get("effect")
    if not isinstance(tables, list) or not tables:
        raise ConfigError(f"{p}: no [[effect]] tables")
    out: dict[str, Effect] = {}
    for i, tab in enumerate(tables):
        out_eff = _user_effect(tab, f"{p}: effect #{i + 1}")
        if out_eff.id in out or out_eff.id in CATALOGUE:
            raise ConfigError(f"{p}: effect id '{out_eff.id}' is defined twice (or is a built-in id)")
        out[out_eff.id] = out_eff
    return out


def _user_effect(tab, where) -> Effect:
    if not isinstance(tab, dict):
        raise ConfigError(f"{where}: must be a table")
    allowed = {"id", "description", "meaning", "features", "needs", "per_flight"}
    bad = set(tab) - allowed
    if bad:
        k = sorted(bad)[0]
        raise ConfigError(f"{where}: unknown key '{k}'{did_you_mean(k, allowed)}; allowed: {sorted(allowed)}")
    eid = tab.get("id")
    if not isinstance(eid, str) or not eid.isidentifier():
        raise ConfigError(f"{where}: 'id' must be an identifier string, got {eid!r}")
    where = f"{where} ('{eid}')"
    feats = tab.get("features")
    if not isinstance(feats, dict) or not feats:
        raise ConfigError(f"{where}: 'features' must map targets to {{param = expression}} tables")
    parsed: dict[str, dict[str, sp.Expr]] = {}
    params: set[str] = set()
    used: set[str] = set()
    for target, table in feats.items():
        if target not in TARGETS:
            raise ConfigError(f"{where}: unknown target '{target}'{did_you_mean(target, TARGETS)}; "
                              f"known: {', '.join(TARGETS)}")
        if not isinstance(table, dict) or not table:
            raise ConfigError(f"{where}: features.{target} must be a table of param = expression")
        parsed[target] = {}
        for name, text in table.items():
            if not name.isidentifier():
                raise ConfigError(f"{where}: parameter name {name!r} is not an identifier")
            if not isinstance(text, str):
                raise ConfigError(f"{where}: features.{target}.{name} must be a string expression")
            expr = parse_expression(text, _EXPR_NAMES, {"g": 9.81},
                                    what=f"{where} features.{target}.{name}")
            parsed[target][name] = expr
            params.add(name)
            used |= {s.name for s in expr.free_symbols}
    meaning = tab.get("meaning", "")
    if not isinstance(meaning, str):
        raise ConfigError(f"{where}: 'meaning' must be a format string")
    if meaning:  # checked once with stand-in values: only {name} / {name:.3g}-style fields
        safe_format(meaning, {**{k: 1.0 for k in params}, "k_D": 1.0}, what=f"{where}: 'meaning'")
    needs = []
    for n in sorted(used):
        needs.extend(_DERIVED_NEEDS.get(n, ((n,),)))
    for n in tab.get("needs", []) or []:
        if not isinstance(n, str):
            raise ConfigError(f"{where}: 'needs' must be a list of signal names")
        needs.append(tuple(n.split("|")))
    desc = tab.get("description", f"user effect {eid}")

    def expr_fn(ctx, consts, _parsed=parsed):
        exprs = _parsed.get(ctx.target)
        if not exprs:
            return {}
        sub = {symbol("speed"): sp.sqrt(symbol("vx") ** 2 + symbol("vy") ** 2),
               symbol("v_axis"): symbol(velocity_of(ctx.target))}
        if ctx.tilt is not None:
            sub[symbol("G")] = ctx.tilt
        return {k: e.subs(sub) for k, e in exprs.items()}

    def interpret_fn(coef, base, _meaning=meaning, _params=tuple(sorted(params))):
        vals = {k: coef.get(k, float("nan")) for k in _params}
        if _meaning:
            text = safe_format(_meaning, {**vals, "k_D": mean_k_drag(base)}, what=f"effect {eid}: 'meaning'")
        else:
            text = f"{eid}: " + ", ".join(f"{k} = {v:.4g}" for k, v in vals.items())
        return Interpretation(text, vals)

    per_flight = tab.get("per_flight", False)
    if not isinstance(per_flight, bool):
        raise ConfigError(f"{where}: 'per_flight' must be true or false, got {per_flight!r}")
    derivative = sorted(u for u in used if is_measured_derivative(u))
    reason = (PER_FLIGHT_REASON if per_flight else
              f"uses {', '.join(derivative)}, a measured derivative (cannot be simulated)"
              if derivative else "")
    return Effect(eid, str(desc), tuple(needs), interpret_fn, expr_fn=expr_fn,
                  targets=tuple(t for t in TARGETS if t in parsed), user=True, per_flight=per_flight,
                  fold_reason=reason)
