"""The catalogue of candidate effects the diagnosis tests against a model's residual.

Each :class:`Effect` is a physical effect the tilt-drag prior leaves out, written as columns that
enter the model LINEARLY in unknown coefficients, so adding an effect is one least-squares refit:

    v̇_axis = prior terms (refit) + Σ_p  coef_p · feature_p(signals)

Every effect states

* ``id`` and ``description``;
* ``needs``: the signals it needs, as groups of alternatives (each group needs ONE available signal);
  ``"@tilt"`` means "the prior has tilt (gravity) terms for the target". An effect whose needs are
  not met is UNTESTABLE (never "absent");
* ``features(ctx) -> {param: column}`` for one target, from the target's :class:`EffectContext`
  (the Dataset's columns on the grid plus the prior's tilt terms). A parameter name used for both
  horizontal targets is ONE coefficient shared by both (e.g. the quadratic-drag ``c`` or the
  attitude biases); axis-specific names (``offset_x``) are separate coefficients;
* ``interpret(coef, base) -> Interpretation``: the fitted coefficients in physical terms;
* ``per_flight``: a condition of the flight rather than of the vehicle (wind, attitude bias): its
  parameters are estimated separately for every flight; on a test flight they are estimated by
  blocked cross-validation on that flight, with everything else fixed from training.

Conventions (droneid frames: world ENU, Z-Y-X Euler, positive pitch = nose down). ``G`` below is
the sum of the prior's terms that contain roll or pitch (for tilt-drag:
``G_x = g cosψ tanθ/cosφ + g sinψ tanφ``, ``G_y = g sinψ tanθ/cosφ − g cosψ tanφ``), and
``k_D`` is the fitted linear drag coefficient of the base model.

==================  ==========================================================================
id                  feature(s) for v̇x (v̇y analogous), coefficient -> physical meaning
==================  ==========================================================================
quadratic_drag      −|v_h| vx (shared c) -> "quadratic drag c_D/m = c 1/m"; once wind is in
                    the model, v is the air velocity v − ŵ (also for anisotropic_drag)
wind                1 (offset_x) -> wind w_x = offset_x / k_D (drag acts on v − w)
attitude_bias       ∂G/∂roll, ∂G/∂pitch (shared) -> bias = −coef (logged − true angle)
attitude_delay      dG/dt from the logged attitude (shared τ) -> "attitude lags by τ"
anisotropic_drag    −(cos2ψ vx + sin2ψ vy)/2 (shared Δk) -> k_x = k̄ + Δk/2, k_y = k̄ − Δk/2
thrust_variation    G · v̇z/g (or G · (a_z cosφ cosθ/g − 1)) -> thrust-balance gain
thrust_direction    G_exact − G, G_exact = g(cosψ tanθ + sinψ tanφ/cosθ) -> weight (1 = exact)
ground_effect       G · exp(−h/h0), h = z − z_ground -> thrust gain at the ground
battery_sag         G · (u/ū) · (V − V̄)/V̄ -> relative thrust change per relative voltage
==================  ==========================================================================

User effects: :func:`load_effects` reads TOML (see ``notes/README_diagnose.md``); expressions are
parsed only with :func:`droneid.expressions.parse_expression`.
"""
from __future__ import annotations

import math
import string
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

from droneid.io_util import load_toml
from droneid.errors import ConfigError, did_you_mean
from droneid.expressions import compile_expression, parse_expression, symbol
from droneid.flight import CANONICAL_SIGNALS

__all__ = [
    "Effect", "EffectContext", "Interpretation", "CATALOGUE", "TILT", "get_effect",
    "load_effects", "time_derivative", "AXIS",
]

#: Pseudo-signal meaning "the prior has tilt terms for this target".
TILT = "@tilt"
#: Horizontal targets the catalogue knows, and their axis letter.
AXIS = {"vx_dot": "x", "vy_dot": "y"}
#: Names user expressions may use besides canonical signals.
DERIVED = {
    "G": "the prior's tilt (gravity) terms for the target, m/s²",
    "vz_dot": "vertical acceleration from vz (central differences), m/s²",
    "speed": "horizontal speed sqrt(vx² + vy²), m/s",
    "v_axis": "the target's own velocity (vx for vx_dot, vy for vy_dot), m/s",
}


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
    """What an effect may read for ONE target: columns on the grid and the prior's tilt terms.

    ``columns`` holds the Dataset's inputs and extras (canonical names) plus derived columns
    (``vz_dot``, ``speed``, ``v_axis`` and ``G`` where computable). ``tilt`` is the prior's tilt
    expression (sympy over canonical symbols) or None; ``options`` holds effect options
    (``ground_h0_m``).
    """
    target: str
    columns: Mapping[str, np.ndarray]
    t: np.ndarray
    flight: np.ndarray
    tilt: sp.Expr | None = None
    g: float = 9.81
    options: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def build(cls, target: str, columns: Mapping[str, np.ndarray], t, flight, tilt=None,
              g: float = 9.81, options: Mapping[str, float] | None = None) -> "EffectContext":
        cols = {k: np.asarray(v, float) for k, v in columns.items()
                if k not in (target, "t") and np.all(np.isfinite(np.asarray(v, float)))}
        t = np.asarray(t, float)
        flight = np.asarray(flight, int)
        if "vz" in cols:
            cols["vz_dot"] = time_derivative(cols["vz"], t, flight)
        if "vx" in cols and "vy" in cols:
            cols["speed"] = np.hypot(cols["vx"], cols["vy"])
        ax = AXIS.get(target)
        if ax and f"v{ax}" in cols:
            cols["v_axis"] = cols[f"v{ax}"]
        ctx = cls(target, cols, t, flight, tilt, g, dict(options or {}))
        if tilt is not None and ctx._can_eval(tilt):
            cols["G"] = ctx.evaluate(tilt)
        return ctx

    @property
    def axis(self) -> str | None:
        return AXIS.get(self.target)

    def available(self) -> set[str]:
        """Names of usable columns, plus ``"@tilt"`` when the prior's tilt terms are computable."""
        names = set(self.columns)
        if "G" in self.columns:
            names.add(TILT)
        return names

    def _can_eval(self, expr) -> bool:
        return all(s.name in self.columns for s in expr.free_symbols)

    def evaluate(self, expr: sp.Expr) -> np.ndarray:
        names = sorted(s.name for s in expr.free_symbols)
        f = compile_expression(expr, names)
        n = self.t.size
        return np.broadcast_to(f({k: self.columns[k] for k in names} or {"_": np.zeros(n)}),
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
    """One candidate effect (see the module docstring)."""
    id: str
    description: str
    needs: tuple[tuple[str, ...], ...]
    feature_fn: Callable[[EffectContext], dict]
    interpret_fn: Callable[[dict, dict], Interpretation]
    explain_signal: str = ""
    user: bool = False
    per_flight: bool = False

    def missing(self, available: Iterable[str]) -> list[str]:
        """Unmet needs, each as 'a|b' alternatives; empty when testable."""
        avail = set(available)
        return ["|".join(_need_label(a) for a in grp) for grp in self.needs
                if not any(a in avail for a in grp)]

    def applies_to(self, target: str) -> bool:
        return target in AXIS or self.user

    def features(self, ctx: EffectContext) -> dict[str, np.ndarray]:
        """``{param: column}`` for ctx's target, or ``{}`` when it does not apply there."""
        if self.missing(ctx.available()):
            return {}
        cols = self.feature_fn(ctx) or {}
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
    return "tilt terms of the prior" if name == TILT else name


# -- the catalogue ------------------------------------------------------------------------------
def _k_mean(base) -> float:
    ks = [k for k in (base.get("k_D") or {}).values() if k is not None and math.isfinite(k)]
    return float(np.mean(ks)) if ks else float("nan")


def _air(ctx, name):
    """The air-relative velocity column when a wind estimate exists, else the ground one."""
    return ctx.columns.get(f"{name}_air", ctx.columns[name])


def _quadratic_drag(ctx):
    if not ctx.axis:
        return {}
    return {"c": -_air(ctx, "speed") * _air(ctx, f"v{ctx.axis}")}


def _quadratic_drag_text(coef, base):
    c = coef.get("c", float("nan"))
    return Interpretation(f"quadratic drag c_D/m = {c:.3g} 1/m", {"c_D_over_m_per_m": c})


def _wind(ctx):
    return {f"offset_{ctx.axis}": np.ones(ctx.t.size)} if ctx.axis else {}


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


def _attitude_bias(ctx):
    if not ctx.axis:
        return {}
    return {"d_roll": ctx.tilt_partial("roll"), "d_pitch": ctx.tilt_partial("pitch")}


def _attitude_bias_text(coef, base):
    # acceleration = G(logged + δ) ≈ G + δ ∂G; bias = logged − true = −δ
    br = -math.degrees(coef.get("d_roll", float("nan")))
    bp = -math.degrees(coef.get("d_pitch", float("nan")))
    return Interpretation(f"roll bias {br:+.2f}°, pitch bias {bp:+.2f}° (logged − true)",
                          {"roll_bias_deg": br, "pitch_bias_deg": bp})


def _attitude_delay(ctx):
    return {"tau": ctx.d_dt(ctx.columns["G"])} if ctx.axis else {}


def _attitude_delay_text(coef, base):
    tau = coef.get("tau", float("nan"))
    word = "lags" if tau >= 0 else "leads"
    return Interpretation(f"attitude {word} acceleration by {abs(tau) * 1000:.0f} ms",
                          {"delay_ms": tau * 1000.0})


def _anisotropic_drag(ctx):
    if not ctx.axis:
        return {}
    c = ctx.columns
    c2, s2 = np.cos(2 * c["yaw"]), np.sin(2 * c["yaw"])
    vx, vy = _air(ctx, "vx"), _air(ctx, "vy")
    if ctx.axis == "x":
        return {"dk": -0.5 * (c2 * vx + s2 * vy)}
    return {"dk": -0.5 * (s2 * vx - c2 * vy)}


def _anisotropic_drag_text(coef, base):
    k = _k_mean(base)
    dk = coef.get("dk", float("nan"))
    kx, ky = k + dk / 2, k - dk / 2
    return Interpretation(f"anisotropic drag k_x = {kx:.3g} 1/s (body forward), "
                          f"k_y = {ky:.3g} 1/s (body left)",
                          {"k_x_per_s": kx, "k_y_per_s": ky, "dk_per_s": dk})


def _thrust_variation(ctx):
    if not ctx.axis:
        return {}
    c = ctx.columns
    if "vz_dot" in c:
        return {"s": c["G"] * c["vz_dot"] / ctx.g}
    return {"s": c["G"] * (c["az"] * np.cos(c["roll"]) * np.cos(c["pitch"]) / ctx.g - 1.0)}


def _thrust_variation_text(coef, base):
    s = coef.get("s", float("nan"))
    return Interpretation(f"thrust departs from hover balance: tilt terms scale with "
                          f"(1 + {s:.2f}·v̇z/g) (1 = thrust follows vertical acceleration)",
                          {"gain": s})


def _thrust_direction(ctx):
    if not ctx.axis:
        return {}
    c = ctx.columns
    r, p, y = c["roll"], c["pitch"], c["yaw"]
    with np.errstate(all="ignore"):
        if ctx.axis == "x":
            exact = ctx.g * (np.cos(y) * np.tan(p) + np.sin(y) * np.tan(r) / np.cos(p))
        else:
            exact = ctx.g * (np.sin(y) * np.tan(p) - np.cos(y) * np.tan(r) / np.cos(p))
    return {"w_exact": exact - c["G"]}


def _thrust_direction_text(coef, base):
    w = coef.get("w_exact", float("nan"))
    return Interpretation(f"exact Z-Y-X thrust direction: weight {w:.2f} on (exact − small-angle) "
                          "tilt terms (1 = exact geometry)", {"weight": w})


def _ground_effect(ctx):
    if not ctx.axis:
        return {}
    h0 = float(ctx.options.get("ground_h0_m", 0.5))
    z = ctx.columns["z"]
    h = np.empty_like(z)
    for f in np.unique(ctx.flight):
        m = ctx.flight == f
        h[m] = np.maximum(z[m] - np.percentile(z[m], 2), 0.0)
    return {"k_ge": ctx.columns["G"] * np.exp(-h / h0)}


def _ground_effect_text(coef, base):
    k = coef.get("k_ge", float("nan"))
    return Interpretation(f"thrust gain near the ground: {100 * k:+.0f} % at the lowest height "
                          "(decaying with height)", {"gain_at_ground": k})


def _command(c):
    if "throttle" in c:
        return c["throttle"]
    motors = [c[f"motor{i}"] for i in range(1, 17) if f"motor{i}" in c]
    return np.mean(motors, axis=0) if motors else c["thrust"]


def _battery_sag(ctx):
    if not ctx.axis:
        return {}
    c = ctx.columns
    u = _command(c)
    v = c["battery_voltage"]
    ub, vb = np.mean(u), np.mean(v)
    if not (abs(ub) > 1e-9 and abs(vb) > 1e-9):
        return {}
    return {"kappa": c["G"] * (u / ub) * (v - vb) / vb}


def _battery_sag_text(coef, base):
    k = coef.get("kappa", float("nan"))
    return Interpretation(f"thrust per command changes by {k:.2f} × ΔV/V̄ (battery sag; "
                          "1 = thrust proportional to voltage)", {"kappa": k})


_CMD = ("throttle", "motor1", "thrust")

#: The built-in effects, by id.
CATALOGUE: dict[str, Effect] = {e.id: e for e in (
    Effect("quadratic_drag", "aerodynamic drag growing with speed squared: −c|v|v",
           (("vx",), ("vy",)), _quadratic_drag, _quadratic_drag_text, "|v| v_axis"),
    Effect("wind", "constant world-frame wind w: linear drag acts on v − w, a constant k_D·w "
           "per axis (the base refit has no intercept, so the offset is not absorbed)",
           (("vx", "vy"),), _wind, _wind_text, "yaw", per_flight=True),
    Effect("attitude_bias", "constant roll/pitch offsets of the logged attitude (rotate with "
           "yaw, unlike wind)", ((TILT,), ("roll",), ("pitch",)), _attitude_bias,
           _attitude_bias_text, "yaw", per_flight=True),
    Effect("attitude_delay", "logged attitude lags the acceleration it causes by τ: "
           "G(att(t + τ)) ≈ G + τ dG/dt", ((TILT,),), _attitude_delay, _attitude_delay_text,
           "dG/dt"),
    Effect("anisotropic_drag", "different linear drag along body x and body y",
           (("vx",), ("vy",), ("yaw",)), _anisotropic_drag, _anisotropic_drag_text, "yaw"),
    Effect("thrust_variation", "thrust departs from hover balance (climbs, descents): the tilt "
           "terms scale with the vertical thrust balance", ((TILT,), ("vz_dot", "az")),
           _thrust_variation, _thrust_variation_text, "vz_dot"),
    Effect("thrust_direction", "exact Z-Y-X thrust geometry instead of the paper's small-angle "
           "tilt terms", ((TILT,), ("roll",), ("pitch",), ("yaw",)), _thrust_direction,
           _thrust_direction_text, "pitch"),
    Effect("ground_effect", "thrust gain near the ground (needs height z)", ((TILT,), ("z",)),
           _ground_effect, _ground_effect_text, "z"),
    Effect("battery_sag", "thrust per command falls with battery voltage (needs a command and "
           "the voltage)", ((TILT,), _CMD, ("battery_voltage",)), _battery_sag,
           _battery_sag_text, "battery_voltage"),
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
_DERIVED_NEEDS = {"G": ((TILT,),), "vz_dot": (("vz",),), "speed": (("vx",), ("vy",)),
                  "v_axis": (("vx", "vy"),)}


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
    if meaning:
        try:
            fields = {f for _, f, _, _ in string.Formatter().parse(meaning) if f}
        except ValueError as exc:
            raise ConfigError(f"{where}: bad 'meaning' format string: {exc}") from None
        extra = {f.split(".")[0].split("[")[0] for f in fields} - params - {"k_D"}
        if extra:
            k = sorted(extra)[0]
            raise ConfigError(f"{where}: 'meaning' uses unknown name '{k}'{did_you_mean(k, params)}; "
                              f"parameters: {sorted(params)}")
        try:
            meaning.format(**{k: 1.0 for k in params}, k_D=1.0)
        except (ValueError, KeyError, IndexError) as exc:
            raise ConfigError(f"{where}: bad 'meaning' format string: {exc}") from None
    needs = []
    for n in sorted(used):
        needs.extend(_DERIVED_NEEDS.get(n, ((n,),)))
    for n in tab.get("needs", []) or []:
        if not isinstance(n, str):
            raise ConfigError(f"{where}: 'needs' must be a list of signal names")
        needs.append(tuple(n.split("|")))
    desc = tab.get("description", f"user effect {eid}")

    def feature_fn(ctx, _parsed=parsed):
        exprs = _parsed.get(ctx.target)
        if not exprs:
            return {}
        return {k: ctx.evaluate(e) for k, e in exprs.items()}

    def interpret_fn(coef, base, _meaning=meaning, _params=tuple(sorted(params))):
        vals = {k: coef.get(k, float("nan")) for k in _params}
        if _meaning:
            text = _meaning.format(**vals, k_D=_k_mean(base))
        else:
            text = f"{eid}: " + ", ".join(f"{k} = {v:.4g}" for k, v in vals.items())
        return Interpretation(text, vals)

    per_flight = tab.get("per_flight", False)
    if not isinstance(per_flight, bool):
        raise ConfigError(f"{where}: 'per_flight' must be true or false, got {per_flight!r}")
    return Effect(eid, str(desc), tuple(needs), feature_fn, interpret_fn, "", user=True,
                  per_flight=per_flight)
