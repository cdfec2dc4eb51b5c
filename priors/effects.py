"""The catalogue of candidate effects the diagnosis tests against a model's residual.

Each :class:`Effect` is a physical effect the prior leaves out, written as columns that enter the
model LINEARLY in unknown coefficients, so adding an effect is one least-squares refit:

    v̇_axis = prior terms (refit) + Σ_p  coef_p · feature_p(signals)

Every effect states

* ``id`` and ``description``;
* ``needs``: the signals it needs, as groups of alternatives (each group needs ONE available signal);
  ``"@tilt"`` means "the prior has thrust-direction terms for the target". An effect whose needs
  are not met is UNTESTABLE (never "absent");
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
  blocked cross-validation on that flight, with everything else fixed from training.

Causal inputs only: effects are built from states and inputs (velocity, attitude, height, logged
thrust / motor signals, battery voltage), never from a measured derivative (``vz_dot`` from
differencing, IMU ``ax ay az``). Those columns exist in an :class:`EffectContext` only when it is
built with ``allow_measured_derivatives=True``; a model using them cannot be simulated.

Conventions (droneid frames: world ENU, Z-Y-X Euler, positive pitch = nose down). ``G`` below is
the prior's thrust-direction term for the target at the scale of the base refit on the training
flights (Σ β_term · term): the sum of its terms with role ``tilt``
(tilt-drag: ``G_x = g cosψ tanθ/cosφ + g sinψ tanφ``) or ``thrust`` (rotor-thrust: logged thrust
along body z), or for priors without roles the terms containing roll or pitch. ``k_D`` is the
fitted linear drag coefficient of the base model (from the role ``drag`` terms).

==================  ==========================================================================
id                  feature(s) for v̇x (v̇y analogous), coefficient -> physical meaning
==================  ==========================================================================
quadratic_drag      −sqrt(vx²+vy²)·vx (shared c) -> c_D/m in 1/m; once wind is in the model,
                    the fit uses the air velocity v − ŵ (also for anisotropic_drag); the
                    folded expression uses v (wind is a condition of the flight)
vertical_drag       v̇z only: −|vz|·vz (c_z) -> vertical c_D/m in 1/m
wind                1 (offset_x) -> wind w_x = offset_x / k_D (drag acts on v − w); per flight
attitude_bias       ∂G/∂roll, ∂G/∂pitch (shared) -> bias = −coef (logged − true); per flight
attitude_delay      dG/dt from the logged attitude (shared τ) -> "attitude lags by τ"
anisotropic_drag    −(cos2ψ vx + sin2ψ vy)/2 (shared Δk) -> k_x = k̄ + Δk/2, k_y = k̄ − Δk/2
thrust_variation    G·(T/T̄ − 1), T the logged thrust proxy (thrust N, else Σ(rpm/10⁴)², else
                    mean motor command, else throttle), T̄ its training mean -> gain (1 = thrust
                    proportional to T); not applicable when G is the logged thrust already
thrust_direction    G_exact − G, G_exact = g(cosψ tanθ + sinψ tanφ/cosθ) -> weight (1 = exact)
thrust_curve        G·((Σω/S̄)/(Σω²/W̄) − 1) (rotor-thrust from rpm) -> thrust ∝ ω^(2−a);
                    not applicable when G is the logged thrust (exact rotation already)
ground_effect       G·exp(−(z − z_ground)/h0), z_ground the 2nd percentile of the training
                    heights, h0 = ``ground_h0_m`` (also v̇z) -> thrust gain at the ground
battery_sag         G·(u/ū)·(V − V̄)/V̄, u the command (throttle, else mean motor command), ū and
                    V̄ training means (also v̇z) -> relative thrust change per relative voltage;
                    not applicable when G comes from measured rotor speeds or thrust
==================  ==========================================================================

User effects: :func:`load_effects` reads TOML (see docs/diagnosis.md); expressions are
parsed only with :func:`droneid.expressions.parse_expression`.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

from droneid.io_util import load_toml
from droneid.errors import ConfigError, did_you_mean
from droneid.expressions import compile_expression, parse_expression, safe_format, symbol
from droneid.flight import CANONICAL_SIGNALS
from droneid.targets import HORIZONTAL, TARGETS, axis_of, velocity_of

__all__ = [
    "Effect", "EffectContext", "Interpretation", "CATALOGUE", "TILT", "get_effect",
    "load_effects", "time_derivative", "MEASURED_DERIVATIVES",
    "is_measured_derivative", "thrust_proxy",
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


def time_derivative(x: np.ndarray, t: np.ndarray, flight: np.ndarray,
                    half_window_s: float = 0.0) -> np.ndarray:
    """d/dt of ``x`` inside each flight's contiguous runs of samples.

    A run breaks where the time step exceeds 1.5× the median step (trimmed gaps). With
    ``half_window_s`` = 0: central differences (one-sided at run ends). Otherwise the slope of a
    least-squares line over ±k samples, k = round(half_window_s / step) (a Savitzky-Golay
    derivative: same phase as central differences, much less noise gain), central differences
    within k samples of a run end.
    """
    x = np.asarray(x, float)
    t = np.asarray(t, float)
    out = np.zeros_like(x)
    if x.size < 2:
        return out
    dt = np.diff(t)
    med = np.median(dt[dt > 0]) if np.any(dt > 0) else 1.0
    brk = np.flatnonzero((np.diff(flight) != 0) | (dt > 1.5 * med) | (dt <= 0)) + 1
    k = int(round(half_window_s / med)) if half_window_s > 0 else 0
    for seg in np.split(np.arange(x.size), brk):
        if seg.size < 2:
            continue
        xs = x[seg]
        d = np.gradient(xs, t[seg])
        if k >= 1 and seg.size > 2 * k + 1:
            j = np.arange(-k, k + 1)
            c = j / (med * np.sum(j * j))
            d[k:-k] = np.convolve(xs, c[::-1], mode="valid")
        out[seg] = d
    return out


@dataclass(frozen=True)
class EffectContext:
    """What an effect may read for ONE target: columns on the grid and the prior's G terms.

    ``columns`` holds the Dataset's inputs and extras (canonical names) plus derived columns
    (``speed``, ``v_axis``, ``G`` where computable, and ``vz_dot`` only with
    ``allow_measured_derivatives``; measured derivatives ``ax ay az *_dot`` are dropped otherwise).
    ``tilt`` is the prior's G expression (sympy over canonical symbols) or None; ``tilt_role`` is
    ``"tilt"`` (thrust direction at hover balance) or ``"thrust"`` (logged thrust); ``options``
    holds effect options (``ground_h0_m``, ``derivative_half_window_s``).
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
    """Fitted coefficients of one effect in physical terms: a sentence and named values."""
    text: str
    values: dict


@dataclass(frozen=True)
class Effect:
    """One candidate effect (see the module docstring).

    Exactly one of ``expr_fn(ctx, constants) -> {param: sympy.Expr}`` (foldable effects) and
    ``column_fn(ctx, constants) -> {param: column}`` computes the features;
    ``constants_fn(ctx) -> {name: float}`` fixes numbers from the training data;
    ``applicable_fn(ctx) -> reason or None`` says when the effect makes no sense for the prior;
    ``data_fn(ctx) -> reason or None`` when the (training) data cannot identify it.
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

    def interpret(self, coef: Mapping[str, float], base: Mapping) -> Interpretation:
        """Physical terms from ``coef`` ({param: value}) and ``base`` info (``k_D``: {target: k})."""
        return self.interpret_fn(dict(coef), dict(base))


def _need_label(name: str) -> str:
    return "thrust-direction (tilt or thrust) terms of the prior" if name == TILT else name


# -- the catalogue ------------------------------------------------------------------------------
_ALL = ("vx_dot", "vy_dot", "vz_dot")


def _k_mean(base) -> float:
    ks = [k for t, k in (base.get("k_D") or {}).items()
          if t in HORIZONTAL and k is not None and math.isfinite(k)]
    return float(np.mean(ks)) if ks else float("nan")


def _sym(name):
    return symbol(name)


def _quadratic_drag(ctx, k):
    return {"c": -sp.sqrt(_sym("vx") ** 2 + _sym("vy") ** 2) * _sym(f"v{ctx.axis}")}


def _quadratic_drag_text(coef, base):
    c = coef.get("c", float("nan"))
    return Interpretation(f"quadratic drag c_D/m = {c:.3g} 1/m", {"c_D_over_m_per_m": c})


def _vertical_drag(ctx, k):
    vz = _sym("vz")
    return {"c_z": -sp.Abs(vz) * vz}


def _vertical_drag_text(coef, base):
    c = coef.get("c_z", float("nan"))
    return Interpretation(f"vertical quadratic drag c_Dz/m = {c:.3g} 1/m", {"c_D_z_over_m_per_m": c})


def _wind(ctx, k):
    return {f"offset_{ctx.axis}": np.ones(ctx.t.size)}


def _wind_text(coef, base):
    kd = base.get("k_D") or {}
    w, parts = {}, []
    for ax, tgt in (("x", "vx_dot"), ("y", "vy_dot")):
        if f"offset_{ax}" not in coef:
            continue
        k = kd.get(tgt)
        off = coef[f"offset_{ax}"]
        w[f"w_{ax}_m_s"] = off / k if k and k > 1e-6 else float("nan")
        w[f"offset_{ax}_m_s2"] = off
        parts.append(w[f"w_{ax}_m_s"])
    if len(parts) == 1:
        ax = "x" if "offset_x" in coef else "y"
        txt = f"wind along {ax} ({'east' if ax == 'x' else 'north'}) ≈ {parts[0]:.2g} m/s"
    else:
        txt = "wind ≈ (" + ", ".join(f"{p:.2g}" for p in parts) + ") m/s"
    if any(not math.isfinite(p) for p in parts):
        txt += " (linear drag k_D not positive: wind undetermined; constant offset " + ", ".join(
            f"{v:.3g}" for k, v in w.items() if k.startswith("offset")) + " m/s²)"
    return Interpretation(txt, w)


def _attitude_bias(ctx, k):
    return {"d_roll": ctx.tilt_partial("roll"), "d_pitch": ctx.tilt_partial("pitch")}


def _attitude_bias_text(coef, base):
    # acceleration = G(logged + δ) ≈ G + δ ∂G; bias = logged − true = −δ
    br = -math.degrees(coef.get("d_roll", float("nan")))
    bp = -math.degrees(coef.get("d_pitch", float("nan")))
    return Interpretation(f"roll bias {br:+.2f}°, pitch bias {bp:+.2f}° (logged − true)",
                          {"roll_bias_deg": br, "pitch_bias_deg": bp})


def _attitude_delay(ctx, k):
    return {"tau": ctx.d_dt(ctx.columns["G"])}


def _attitude_delay_text(coef, base):
    tau = coef.get("tau", float("nan"))
    word = "lags" if tau >= 0 else "leads"
    return Interpretation(f"attitude {word} acceleration by {abs(tau) * 1000:.0f} ms",
                          {"delay_ms": tau * 1000.0})


def _anisotropic_drag(ctx, k):
    psi, vx, vy = _sym("yaw"), _sym("vx"), _sym("vy")
    c2, s2 = sp.cos(2 * psi), sp.sin(2 * psi)
    if ctx.axis == "x":
        return {"dk": -(c2 * vx + s2 * vy) / 2}
    return {"dk": -(s2 * vx - c2 * vy) / 2}


def _anisotropic_drag_text(coef, base):
    k = _k_mean(base)
    dk = coef.get("dk", float("nan"))
    kx, ky = k + dk / 2, k - dk / 2
    return Interpretation(f"anisotropic drag k_x = {kx:.3g} 1/s (body forward), "
                          f"k_y = {ky:.3g} 1/s (body left)",
                          {"k_x_per_s": kx, "k_y_per_s": ky, "dk_per_s": dk})


def thrust_proxy(available: Iterable[str]) -> tuple[str, sp.Expr] | None:
    """(description, sympy expression) of the logged quantity most nearly proportional to the
    collective thrust, or None: ``thrust`` (N), else Σ(rpm_i/10⁴)² (rotor momentum theory),
    else the mean motor command, else ``throttle``."""
    have = set(available)
    if "thrust" in have:
        return "thrust", _sym("thrust")
    for src, label in (("rpm", "Σ(rpm/10⁴)²"), ("motor", "mean motor command")):
        n = 0
        while f"{src}{n + 1}" in have:
            n += 1
        if n:
            if src == "rpm":
                return label, sp.Add(*[(_sym(f"rpm{i}") / 10_000) ** 2 for i in range(1, n + 1)])
            return label, sp.Add(*[_sym(f"motor{i}") for i in range(1, n + 1)]) / n
    if "throttle" in have:
        return "throttle", _sym("throttle")
    return None


def _command(available: Iterable[str]) -> tuple[str, sp.Expr] | None:
    """The collective COMMAND (what the battery's voltage scales into thrust): throttle, else
    the mean motor command; None without either."""
    have = set(available)
    if "throttle" in have:
        return "throttle", _sym("throttle")
    motors = [f"motor{i}" for i in range(1, 17) if f"motor{i}" in have]
    if motors:
        return "mean motor command", sp.Add(*[_sym(m) for m in motors]) / len(motors)
    return None


def _needs_measured_thrust(ctx) -> str | None:
    if ctx.tilt_role == "thrust":
        return ("the prior's thrust term is the logged thrust already (rotor-thrust): thrust "
                "variation is in the prior")
    return None


def _thrust_variation_consts(ctx):
    _, e = thrust_proxy(ctx.columns)
    return {"T_mean": float(np.mean(ctx.evaluate(e)))}


def _thrust_variation(ctx, k):
    _, e = thrust_proxy(ctx.columns)
    if not abs(k.get("T_mean", 0.0)) > 1e-12:
        return {}
    return {"s": ctx.tilt * (e / sp.Float(k["T_mean"]) - 1)}


def _thrust_variation_text(coef, base):
    s = coef.get("s", float("nan"))
    return Interpretation(f"thrust departs from hover balance: the fitted tilt terms scale with "
                          f"(1 + {s:.2f}·(T/T̄ − 1)), T the logged thrust proxy (1 = thrust "
                          "proportional to it)", {"gain": s})


def _rpm_sums(available):
    """(Σ ω_i, Σ ω_i²) over the logged motor speeds rpm1..rpmN, in 10⁴ rpm; None without them."""
    have, n = set(available), 0
    while f"rpm{n + 1}" in have:
        n += 1
    if not n:
        return None
    w = [_sym(f"rpm{i}") / 10_000 for i in range(1, n + 1)]
    return sp.Add(*w), sp.Add(*[x ** 2 for x in w])


def _thrust_curve_applies(ctx) -> str | None:
    if ctx.tilt_role != "thrust":
        return "needs a prior whose thrust term comes from motor speeds (rotor-thrust)"
    if _rpm_sums(ctx.columns) is None:
        return "needs motor speeds rpm1..rpmN"
    return None


def _thrust_curve_consts(ctx):
    s, w = _rpm_sums(ctx.columns)
    return {"S_mean": float(np.mean(ctx.evaluate(s))), "W_mean": float(np.mean(ctx.evaluate(w)))}


def _thrust_curve(ctx, k):
    sums = _rpm_sums(ctx.columns)
    if sums is None or not (k.get("S_mean", 0.0) > 0 and k.get("W_mean", 0.0) > 0):
        return {}
    s, w = sums
    return {"a": ctx.tilt * ((s / sp.Float(k["S_mean"])) / (w / sp.Float(k["W_mean"])) - 1)}


def _thrust_curve_text(coef, base):
    a = coef.get("a", float("nan"))
    return Interpretation(f"rotor thrust grows as ω^{2 - a:.2f} rather than ω² (thrust curve; "
                          f"a = {a:.2f})", {"a": a, "exponent": 2 - a})


def _exact_geometry(ctx) -> str | None:
    if ctx.tilt_role == "thrust":
        return "the prior's thrust term uses the exact rotation already (rotor-thrust)"
    return None


def _thrust_direction(ctx, k):
    r, p, y, g = _sym("roll"), _sym("pitch"), _sym("yaw"), sp.Float(ctx.g)
    if ctx.axis == "x":
        exact = g * (sp.cos(y) * sp.tan(p) + sp.sin(y) * sp.tan(r) / sp.cos(p))
    else:
        exact = g * (sp.sin(y) * sp.tan(p) - sp.cos(y) * sp.tan(r) / sp.cos(p))
    return {"w_exact": exact - ctx.tilt}


def _thrust_direction_text(coef, base):
    w = coef.get("w_exact", float("nan"))
    return Interpretation(f"exact Z-Y-X thrust direction: weight {w:.2f} on (exact − small-angle) "
                          "tilt terms (1 = exact geometry)", {"weight": w})


def _ground_consts(ctx):
    return {"z_ground": float(np.percentile(ctx.columns["z"], 2)),
            "h0": float(ctx.options.get("ground_h0_m", 0.5))}


def _ground_heights(ctx) -> str | None:
    """Ground effect is identifiable only when the heights span at least h0 above the lowest
    one: at a nearly constant height exp(−(z − z_ground)/h0) is G plus a tiny G·Δz term that
    fits whatever correlates with height-hold errors, not a ground effect."""
    z = ctx.columns["z"]
    span = float(np.percentile(z, 98) - np.percentile(z, 2))
    h0 = float(ctx.options.get("ground_h0_m", 0.5))
    if span < h0:
        return (f"the training heights span only {span:.2g} m (< h0 = {h0:g} m): a ground "
                "effect cannot be told from a constant thrust gain")
    return None


def _ground_effect(ctx, k):
    return {"k_ge": ctx.tilt * sp.exp(-(_sym("z") - sp.Float(k["z_ground"])) / sp.Float(k["h0"]))}


def _ground_effect_text(coef, base):
    k = coef.get("k_ge", float("nan"))
    return Interpretation(f"thrust gain near the ground: {100 * k:+.0f} % at the training flights' "
                          "ground height (decaying with height)", {"gain_at_ground": k})


def _battery_applicable(ctx) -> str | None:
    if ctx.tilt is not None and ctx.tilt_role == "thrust" and any(
            s.name == "thrust" or s.name.startswith("rpm") for s in ctx.tilt.free_symbols):
        return ("the prior's thrust comes from measured rotor speeds or thrust, which already "
                "include the battery's voltage")
    return None


def _battery_consts(ctx):
    _, u = _command(ctx.columns)
    return {"u_mean": float(np.mean(ctx.evaluate(u))),
            "V_mean": float(np.mean(ctx.columns["battery_voltage"]))}


def _battery_sag(ctx, k):
    _, u = _command(ctx.columns)
    ub, vb = k.get("u_mean", 0.0), k.get("V_mean", 0.0)
    if not (abs(ub) > 1e-9 and abs(vb) > 1e-9):
        return {}
    v = _sym("battery_voltage")
    return {"kappa": ctx.tilt * (u / sp.Float(ub)) * (v - sp.Float(vb)) / sp.Float(vb)}


def _battery_sag_text(coef, base):
    k = coef.get("kappa", float("nan"))
    return Interpretation(f"thrust per command changes by {k:.2f} × ΔV/V̄ (battery sag; "
                          "1 = thrust proportional to voltage)", {"kappa": k})


_THRUST_SIGNALS = ("thrust", "rpm1", "motor1", "throttle")
_CMD = ("throttle", "motor1")
_PER_FLIGHT = "a condition of one flight (estimated per flight), not of the vehicle"

#: The built-in effects, by id.
CATALOGUE: dict[str, Effect] = {e.id: e for e in (
    Effect("quadratic_drag", "aerodynamic drag growing with speed squared: −c|v|v",
           (("vx",), ("vy",)), _quadratic_drag_text, expr_fn=_quadratic_drag,
           explain_signal="|v| v_axis"),
    Effect("vertical_drag", "vertical aerodynamic drag growing with climb rate squared: −c_z|vz|vz",
           (("vz",),), _vertical_drag_text, expr_fn=_vertical_drag, targets=("vz_dot",),
           explain_signal="vz"),
    Effect("wind", "constant world-frame wind w: linear drag acts on v − w, a constant k_D·w "
           "per axis (the base refit has no intercept, so the offset is not absorbed)",
           (("vx", "vy"),), _wind_text, column_fn=_wind, explain_signal="yaw", per_flight=True,
           fold_reason=_PER_FLIGHT),
    Effect("attitude_bias", "constant roll/pitch offsets of the logged attitude (rotate with "
           "yaw, unlike wind)", ((TILT,), ("roll",), ("pitch",)), _attitude_bias_text,
           column_fn=_attitude_bias, targets=_ALL, explain_signal="yaw", per_flight=True,
           fold_reason=_PER_FLIGHT),
    Effect("attitude_delay", "logged attitude lags the acceleration it causes by τ: "
           "G(att(t + τ)) ≈ G + τ dG/dt", ((TILT,),), _attitude_delay_text,
           column_fn=_attitude_delay, targets=_ALL, explain_signal="dG/dt",
           fold_reason="needs dG/dt, a time derivative of the logged attitude (not an "
                       "instantaneous function of states and inputs)"),
    Effect("anisotropic_drag", "different linear drag along body x and body y",
           (("vx",), ("vy",), ("yaw",)), _anisotropic_drag_text, expr_fn=_anisotropic_drag,
           explain_signal="yaw"),
    Effect("thrust_variation", "thrust departs from hover balance (climbs, descents): the tilt "
           "terms scale with the logged thrust relative to its training mean",
           ((TILT,), _THRUST_SIGNALS), _thrust_variation_text, expr_fn=_thrust_variation,
           constants_fn=_thrust_variation_consts, applicable_fn=_needs_measured_thrust,
           explain_signal="thrust"),
    Effect("thrust_curve", "rotor thrust is not exactly ∝ ω² (inflow, motor and propeller "
           "curves): the thrust terms scale with (1 + a·((Σω/S̄)/(Σω²/W̄) − 1)), i.e. T ∝ ω^(2−a) "
           "near the training mean", ((TILT,), ("rpm1",)), _thrust_curve_text, expr_fn=_thrust_curve,
           constants_fn=_thrust_curve_consts, applicable_fn=_thrust_curve_applies, targets=_ALL,
           explain_signal="thrust"),
    Effect("thrust_direction", "exact Z-Y-X thrust geometry instead of the paper's small-angle "
           "tilt terms", ((TILT,), ("roll",), ("pitch",), ("yaw",)), _thrust_direction_text,
           expr_fn=_thrust_direction, applicable_fn=_exact_geometry, explain_signal="pitch"),
    Effect("ground_effect", "thrust gain near the ground (needs height z)", ((TILT,), ("z",)),
           _ground_effect_text, expr_fn=_ground_effect, constants_fn=_ground_consts,
           data_fn=_ground_heights,
           targets=_ALL, explain_signal="z"),
    Effect("battery_sag", "thrust per command falls with battery voltage (needs a command and "
           "the voltage)", ((TILT,), _CMD, ("battery_voltage",)), _battery_sag_text,
           expr_fn=_battery_sag, constants_fn=_battery_consts, applicable_fn=_battery_applicable,
           targets=_ALL, explain_signal="battery_voltage"),
)}


def get_effect(effect_id: str, effects: Mapping[str, Effect] | None = None) -> Effect:
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
        if target not in ("vx_dot", "vy_dot", "vz_dot"):
            raise ConfigError(f"{where}: unknown target '{target}'"
                              f"{did_you_mean(target, ['vx_dot', 'vy_dot', 'vz_dot'])}")
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
               symbol("v_axis"): symbol(f"v{ctx.axis}")}
        if ctx.tilt is not None:
            sub[symbol("G")] = ctx.tilt
        return {k: e.subs(sub) for k, e in exprs.items()}

    def interpret_fn(coef, base, _meaning=meaning, _params=tuple(sorted(params))):
        vals = {k: coef.get(k, float("nan")) for k in _params}
        if _meaning:
            text = safe_format(_meaning, {**vals, "k_D": _k_mean(base)}, what=f"effect {eid}: 'meaning'")
        else:
            text = f"{eid}: " + ", ".join(f"{k} = {v:.4g}" for k, v in vals.items())
        return Interpretation(text, vals)

    per_flight = tab.get("per_flight", False)
    if not isinstance(per_flight, bool):
        raise ConfigError(f"{where}: 'per_flight' must be true or false, got {per_flight!r}")
    derivative = sorted(u for u in used if is_measured_derivative(u))
    reason = (_PER_FLIGHT if per_flight else
              f"uses {', '.join(derivative)}, a measured derivative (cannot be simulated)"
              if derivative else "")
    return Effect(eid, str(desc), tuple(needs), interpret_fn, expr_fn=expr_fn,
                  targets=tuple(t for t in _ALL if t in parsed), user=True, per_flight=per_flight,
                  fold_reason=reason)
