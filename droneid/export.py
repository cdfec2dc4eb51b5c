"""Export final models (:class:`droneid.closed_form.IdentifiedModel`) as self-contained code.

``export_models(models, to)`` returns the text of one file, generated through sympy's printers:

``python``
    a module with one function per target, the signals as keyword arguments (numbers or numpy
    arrays): ``vx_dot(*, pitch, roll, vx, yaw) -> m/s²``; needs numpy only.
``c``
    C99 with ``double vx_dot(double pitch, double roll, double vx, double yaw)`` per target
    (arguments in alphabetical order; compile with ``-lm``).
``matlab``
    one MATLAB / Octave function file: ``m = <name>()`` returns a struct of function handles,
    ``m.vx_dot(pitch, roll, vx, yaw)`` (element-wise, so vectors work); ``name`` must match the
    file name.
``latex``
    one ``equation`` per target, roll φ, pitch θ, yaw ψ, velocities v_x, ...

Each file starts with a comment that states the inputs with their units and, when the result
records them (``Provenance.signal_sources``), the raw log field each input came from and the
normalisation applied to it (e.g. ``motor1 [1]: RCOU.C1 (PWM 1100-1900 us -> 0..1)``), droneid's
conventions (ENU world, FLU body, Z-Y-X Euler, positive pitch = nose down, seconds), the input
delays (which input to feed at t − d) and where the models come from (droneid version, source
result). The equations in the header are written in the file's own language (C and MATLAB
never show Python's ``**``).
"""
from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np
import sympy as sp

from . import __version__
from .errors import ConfigError, MissingSignalError, check_choice
from .expressions import round_expr
from .flight import canonical_unit
from .closed_form import IdentifiedModel
from .rotation import _SPEED_UNIT, KNOWN_TERMS, RotationModel, TranslationModel
from .targets import state_of

__all__ = ["FORMATS", "export_models", "input_sources", "CONVENTIONS", "VEHICLE_FORMATS", "export_vehicle"]

FORMATS = ("python", "c", "matlab", "latex")

CONVENTIONS = ("world frame ENU (x east, y north, z up); body frame FLU (x forward, y left, z up); "
               "attitude as Z-Y-X Euler angles in rad: yaw counter-clockwise from east, then pitch "
               "(positive = nose down), then roll (positive = right side down); velocities in the "
               "world frame; time in s")

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_LATEX_NAMES = {"roll": r"\phi", "pitch": r"\theta", "yaw": r"\psi", "vx": "v_x", "vy": "v_y", "vz": "v_z",
                "wx": r"\omega_x", "wy": r"\omega_y", "wz": r"\omega_z"}


def _unit(signal: str) -> str:
    try:
        return canonical_unit(signal)
    except MissingSignalError:
        return "as logged (not a canonical signal)"


def _equation(m: IdentifiedModel, to: str) -> str:
    """The model's right-hand side in the syntax of language ``to`` (4 significant figures)."""
    if to == "python":
        return m.text()
    e = round_expr(m.expr, 4)
    if to == "c":
        return sp.ccode(e, standard="C99")
    if to == "matlab":
        return sp.octave_code(e)
    return sp.latex(e)


def input_sources(provenance) -> dict:
    """{signal: [(unit, source), ...]} from a result's provenance (the ``train`` and ``test``
    lists of flight provenances, each with ``signal_sources`` rows [name, unit, source]: the raw
    log field and the normalisation the reader applied); each distinct reading once."""
    found: dict[str, list] = {}
    flights = []
    if isinstance(provenance, dict):
        for role in ("train", "test"):
            flights += list(provenance.get(role) or ())
    for fl in flights:
        for row in (fl.get("signal_sources") or ()) if isinstance(fl, dict) else ():
            if isinstance(row, (list, tuple)) and len(row) == 3 and all(isinstance(x, str) for x in row):
                if (row[1], row[2]) not in found.setdefault(row[0], []):
                    found[row[0]].append((row[1], row[2]))
    return found


def _input_unit(signal: str, sources: dict) -> str:
    """The unit the data of ``signal`` had (as recorded; e.g. erpm), else its canonical unit."""
    units = {u for u, _ in sources.get(signal, ())}
    return units.pop() if len(units) == 1 else _unit(signal)


def _input_line(signal: str, sources: dict) -> str:
    fields = [src for _, src in sources.get(signal, ()) if src]
    return f"{signal} [{_input_unit(signal, sources)}]" + (f" from {' | '.join(fields)}" if fields else "")


def _header(models: Sequence[IdentifiedModel], source: str, to: str = "python",
            sources: dict | None = None) -> list[str]:
    """The header lines (without comment markers); equations in the syntax of ``to``."""
    sources = sources or {}
    lines = [f"Identified models exported by droneid {__version__}"
             + (f" from {source}" if source else "") + ".",
             "Conventions: " + CONVENTIONS + ".", ""]
    for m in models:
        lines.append(f"{m.target} ({m.unit}) = {_equation(m, to)}")
        if m.description:     # prose, but it may quote a formula in Python's syntax
            lines.append(f"  what: {m.description if to == 'python' else m.description.replace('**', '^')}")
        if not m.signals:
            lines.append("  inputs: none (a constant)")
        else:
            lines.append("  inputs (unit, then the log field and its normalisation when the result records it):")
            lines.extend(f"    {_input_line(s, sources)}" for s in m.signals)
        if m.delays_s:
            lines.append("  delays: " + ", ".join(f"feed {s} at t - {d:g} s" for s, d in sorted(m.delays_s.items())))
        else:
            lines.append("  delays: none (every input at time t)")
    return lines


def _check(models: Sequence[IdentifiedModel]) -> list[IdentifiedModel]:
    models = list(models)
    if not models or not all(isinstance(m, IdentifiedModel) for m in models):
        raise ConfigError("export needs a non-empty sequence of IdentifiedModel")
    seen = set()
    for m in models:
        for name in (m.target, *m.signals):
            if not _IDENT.match(name):
                raise ConfigError(f"cannot export {m.target}: {name!r} is not a valid identifier in code")
        if m.target in seen:
            raise ConfigError(f"two models of {m.target}")
        seen.add(m.target)
    return models


def export_models(models: Sequence[IdentifiedModel], to: str, source: str = "", name: str = "droneid_model",
                  inputs: dict | None = None) -> str:
    """The text of one file holding every model, in format ``to`` (one of :data:`FORMATS`).

    ``source`` names where the models come from (e.g. the result.json path) for the header;
    ``name`` is the MATLAB function name (the file must be called ``<name>.m``); ``inputs`` maps
    a signal to its unit, raw log field and normalisation (:func:`input_sources` of the result's
    provenance) for the header."""
    check_choice("to", to, FORMATS, owner="export")
    models = _check(models)
    header = _header(models, source, to, inputs)
    if to == "python":
        return _python(models, header, inputs or {})
    if to == "c":
        return _c(models, header)
    if to == "matlab":
        if not _IDENT.match(name):
            raise ConfigError(f"The 'name' parameter of export must be a MATLAB identifier (the file name "
                              f"without .m). Got {name!r} instead.")
        return _matlab(models, header, name)
    return _latex(models, header)


def _python(models, header, sources) -> str:
    from sympy.printing.numpy import NumPyPrinter
    out = ['"""' + "\n".join(header).replace('"""', "'''").replace("\\", "\\\\") + '\n"""', "import numpy", ""]
    for m in models:
        printer = NumPyPrinter({"fully_qualified_modules": True})
        body = printer.doprint(m.expr)
        args = ", ".join(m.signals)
        sig = f"def {m.target}(*, {args}):" if args else f"def {m.target}(**_ignored):"
        doc = f"{m.target} in {m.unit}; inputs: " + (", ".join(f"{s} [{_input_unit(s, sources)}]" for s in m.signals) or "none")
        if m.delays_s:
            doc += "; delays: " + ", ".join(f"{s} at t - {d:g} s" for s, d in sorted(m.delays_s.items()))
        out += ["", f"{sig}", f'    """{doc}."""']
        out += [f"    return {body}", ""]
    return "\n".join(out).rstrip() + "\n"


def _c(models, header) -> str:
    out = ["/*"] + [(" * " + h).rstrip() for h in header] + [
        " *", " * C99; compile with -lm. Arguments in alphabetical order of the signal names.", " */",
        "#include <math.h>", ""]
    for m in models:
        args = ", ".join(f"double {s}" for s in m.signals) or "void"
        out += [f"/* {m.target} in {m.unit} */", f"double {m.target}({args})", "{",
                f"    return {sp.ccode(m.expr, standard='C99')};", "}", ""]
    return "\n".join(out)


def _matlab(models, header, name) -> str:
    out = [f"function m = {name}()"] + [("% " + h).rstrip() for h in header] + [
        "%", f"% Usage: m = {name}(); a = m.{models[0].target}({', '.join(models[0].signals)});",
        "% (element-wise: vectors of samples work; arguments in alphabetical order)"]
    out += [f"  m.{mm.target} = @{mm.target};" for mm in models] + ["end", ""]
    for mm in models:
        args = ", ".join(mm.signals)
        out += [f"function out = {mm.target}({args})", f"  % {mm.target} in {mm.unit}",
                f"  out = {sp.octave_code(mm.expr)};", "end", ""]
    return "\n".join(out)


def _latex(models, header) -> str:
    out = [("% " + h).rstrip() for h in header] + [""]
    for m in models:
        names = {x: _LATEX_NAMES.get(x.name, _latex_name(x.name)) for x in m.expr.free_symbols}
        lhs = _LATEX_NAMES.get(state_of(m.target), _latex_name(state_of(m.target)))
        lhs = rf"\dot{{{lhs}}}" if m.target.endswith("_dot") else _latex_name(m.target)
        out += [r"\begin{equation}", f"  {lhs} = {sp.latex(m.expr, symbol_names=names)}", r"\end{equation}", ""]
    return "\n".join(out)


def _latex_name(s: str) -> str:
    mt = re.match(r"^([A-Za-z]+)_?(\d+)$", s)
    if mt:
        return rf"\mathrm{{{mt.group(1)}}}_{{{mt.group(2)}}}"
    return r"\mathrm{" + s.replace("_", r"\_") + "}"


# -- the whole vehicle: 6-DOF step function --------------------------------------------------------
VEHICLE_FORMATS = ("python", "c")


def _f(x) -> str:
    return repr(float(x))


def _vehicle_spec(translation, rotation) -> dict:
    """Constants of a :class:`droneid.rotation.TranslationModel` and a
    :class:`droneid.rotation.RotationModel`, checked for export."""
    if not isinstance(translation, TranslationModel) or not isinstance(rotation, RotationModel):
        raise ConfigError("export_vehicle needs a droneid.rotation.TranslationModel and a RotationModel; "
                          f"got {type(translation).__name__} and {type(rotation).__name__}")
    if translation.rad_s_per_rpm != rotation.rad_s_per_rpm:
        raise ConfigError("export_vehicle: the translation and the rotation read the motor speeds in "
                          "different units (rad_s_per_rpm)")
    unknown = [t for t in rotation.terms if t not in KNOWN_TERMS]
    if unknown:
        raise ConfigError(f"export_vehicle: unknown rotational term(s) {', '.join(unknown)}")
    return {"M": rotation.layout.motors, "P": rotation.layout.patterns(),
            "scale": rotation.rad_s_per_rpm / _SPEED_UNIT, "d_t": int(translation.delay_steps),
            "d_r": int(rotation.delay_steps), "lp": rotation.lowpass_tau_s, "centre": rotation.centre_tau_s,
            "bw": rotation.balance_weight_s,
            "prior": (np.zeros(rotation.layout.motors) if rotation.balance_prior is None
                      else np.asarray(rotation.balance_prior, float)),
            "k_T": translation.k_thrust, "drag": np.asarray(translation.drag, float), "g": translation.g,
            "terms": tuple(rotation.terms), "coef": [np.asarray(c, float) for c in rotation.coef],
            "trim": np.asarray(rotation.trim, float), "layout": rotation.layout.name}


def _axis_expr(spec: dict, k: int) -> str:
    """ω̇_k as an expression in ``mix[k]``, ``S``, ``w[]``, ``vb[]``, ``spin`` (C and Python alike),
    the columns in the order of :func:`droneid.rotation._rotation_columns`."""
    terms, c = spec["terms"], spec["coef"][k]
    cols = [f"mix[{k}]"]
    if "centre" in terms:
        cols.append("S")
    if "damping" in terms:
        cols.append(f"(-w[{k}])")
    if "gyro" in terms:
        i, j = [(1, 2), (2, 0), (0, 1)][k]
        cols.append(f"w[{i}]*w[{j}]")
    if "spinup" in terms and k == 2:
        cols.append("spin")
    if k < 2:
        j, sign = ((1, "+"), (0, "-"))[k]
        if "rotor_drag" in terms:
            cols.append(f"({sign}vb[{j}])")
        if "rotor_drag_thrust" in terms:
            cols.append(f"({sign}vb[{j}]*S)")
    if len(cols) != c.size:
        raise ConfigError(f"export_vehicle: axis {k} has {c.size} coefficients for {len(cols)} columns")
    return " + ".join([f"({_f(ci)})*{col}" for ci, col in zip(c, cols)] + [f"({_f(spec['trim'][k])})"])


def _vehicle_header(spec: dict, source: str) -> list[str]:
    return [
        f"droneid {__version__}: the whole vehicle (6-DOF), stepped open loop from motor speeds.",
        f"Source: {source or 'droneid.rotation models'}. Rotor layout: {spec['layout']}.",
        "State x[13]: p (m, world ENU) 0:3, v (m/s, world ENU) 3:6, q (qw, qx, qy, qz; Hamilton, FLU body",
        "to ENU world, unit norm) 6:10, w (rad/s, body FLU) 10:13.",
        f"Inputs: the logged motor speeds rpm[{spec['M']}] at each step, fed to the input conditioner,",
        "which returns s_t, s_r, rate_r for that step (held over it): s = (rpm * "
        f"{_f(spec['scale'])})^2, i.e. (rotor speed / 1000 rad/s)^2;",
        f"s_t: translation, motor speeds {spec['d_t']} step(s) earlier; s_r, rate_r: rotation, motor speeds "
        f"{spec['d_r']} step(s) earlier,",
        f"low-passed (time constant {spec['lp']} s), centred ({spec['centre']} s) and balanced about their mean",
        f"since the first step (prior weight {spec['bw']} s); rate_r: rotor speed rate, 1/s.",
        "Translation: v' = R e_z k_T sum(s_t) - R diag(drag) R^T v - g e_z; "
        f"k_T = {_f(spec['k_T'])} m/s^2, drag = {', '.join(_f(d) for d in spec['drag'])} 1/s, g = {_f(spec['g'])}.",
        "Rotation (rad/s^2): w'_k = coefficients . columns + trim; mix = P s_r (roll, pitch, yaw patterns of",
        "the layout), S = sum(s_r), vb = R^T v (body velocity, m/s), spin = yaw pattern . rate_r:",
        *[f"  w'_{k} = {_axis_expr(spec, k)}" for k in range(3)],
        "Integration: classical RK4, quaternion renormalised at every stage and after the step",
        "(as droneid.openloop.simulate).",
    ]


def export_vehicle(translation, rotation, to: str, source: str = "", dt_s: float = 0.01) -> str:
    """The text of one file with the full 6-DOF model in ``to`` (``"python"`` or ``"c"``).

    The file holds an input conditioner (motor speeds -> the model's inputs, causal, one step at a
    time: delays, low-pass, centring, the running balance, rotor speed rates), the state derivative
    and one RK4 step (``dt_s`` seconds by default; the conditioner's time constants assume the same
    step). Python: ``Inputs().push(rpm) -> (s_t, s_r, rate_r)``, ``step(x, s_t, s_r, rate_r, dt)``;
    C99: ``droneid_inputs_init``, ``droneid_inputs_push``, ``droneid_step`` (compile with -lm).
    """
    if to not in VEHICLE_FORMATS:
        check_choice("to", to, VEHICLE_FORMATS, owner="export_vehicle")
    spec = _vehicle_spec(translation, rotation)
    header = _vehicle_header(spec, source)
    return _vehicle_python(spec, header, dt_s) if to == "python" else _vehicle_c(spec, header, dt_s)


def _alpha(tau, dt_s: float) -> str:
    return "None" if tau is None else _f(min(1.0, dt_s / float(tau)))


def _vehicle_python(spec: dict, header: list[str], dt_s: float) -> str:
    M, P = spec["M"], spec["P"]
    rows = ", ".join("[" + ", ".join(_f(v) for v in P[k]) + "]" for k in range(3))
    bw = "None" if spec["bw"] is None else _f(spec["bw"])
    return '\n'.join(['"""' + "\n".join(header).replace("\\", "\\\\") + '\n"""', f'''import math

M = {M}
DT = {_f(dt_s)}
SCALE = {_f(spec["scale"])}          # (rotor speed / 1000 rad/s) per logged rpm
DELAY_T, DELAY_R = {spec["d_t"]}, {spec["d_r"]}
LOWPASS_A = {_alpha(spec["lp"], dt_s)}
CENTRE_A = {_alpha(spec["centre"], dt_s)}
BALANCE_W = {bw}
PRIOR = [{", ".join(_f(v) for v in spec["prior"])}]
P = [{rows}]
K_T, G = {_f(spec["k_T"])}, {_f(spec["g"])}
DRAG = [{", ".join(_f(v) for v in spec["drag"])}]


class Inputs:
    """Motor speeds to the model's inputs, one step at a time (causal)."""

    def __init__(self, dt=DT):
        self.dt = dt
        self.hist = None
        self.lp = self.ema = self.prev = None
        self.sum = [0.0] * M
        self.t = 0.0

    def push(self, rpm):
        """rpm: the M motor speeds of this step as logged -> (s_t, s_r, rate_r), lists of M."""
        om_now = [float(r) * SCALE for r in rpm]
        if self.hist is None:
            self.hist = [om_now] * (max(DELAY_T, DELAY_R) + 1)
        self.hist = self.hist[1:] + [om_now]
        s_t = [o * o for o in self.hist[-1 - DELAY_T]]
        om = self.hist[-1 - DELAY_R]
        if LOWPASS_A is not None:
            self.lp = om if self.lp is None else [LOWPASS_A * o + (1.0 - LOWPASS_A) * y for o, y in zip(om, self.lp)]
            om = self.lp
        rate = [0.0] * M if self.prev is None else [(o - p) / self.dt for o, p in zip(om, self.prev)]
        self.prev = om
        s = [o * o for o in om]
        if CENTRE_A is not None:
            self.ema = s if self.ema is None else [CENTRE_A * v + (1.0 - CENTRE_A) * e for v, e in zip(s, self.ema)]
            s = [v - e for v, e in zip(s, self.ema)]
        if BALANCE_W is not None:
            self.sum = [a + v * self.dt for a, v in zip(self.sum, s)]
            self.t += self.dt
            s = [v - (a + BALANCE_W * p) / (self.t + BALANCE_W) for v, a, p in zip(s, self.sum, PRIOR)]
        return s_t, s, rate


def _rot(q):
    n = math.sqrt(sum(c * c for c in q))
    w, x, y, z = (c / n for c in q)
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def derivative(x, s_t, s_r, rate_r):
    """dx/dt (list of 13) of the state x (13) with the inputs of this step."""
    R = _rot(x[6:10])
    v, w = x[3:6], x[10:13]
    vb = [sum(R[i][j] * v[i] for i in range(3)) for j in range(3)]
    thrust = K_T * sum(s_t)
    dv = [R[i][2] * thrust - sum(R[i][j] * DRAG[j] * vb[j] for j in range(3)) for i in range(3)]
    dv[2] -= G
    mix = [sum(P[k][i] * s_r[i] for i in range(M)) for k in range(3)]
    S = sum(s_r)
    spin = sum(P[2][i] * rate_r[i] for i in range(M))
    dw = [{_axis_expr(spec, 0)},
          {_axis_expr(spec, 1)},
          {_axis_expr(spec, 2)}]
    qw, qx, qy, qz = x[6:10]
    dq = [0.5 * (-qx * w[0] - qy * w[1] - qz * w[2]), 0.5 * (qw * w[0] + qy * w[2] - qz * w[1]),
          0.5 * (qw * w[1] - qx * w[2] + qz * w[0]), 0.5 * (qw * w[2] + qx * w[1] - qy * w[0])]
    return list(v) + dv + dq + dw


def _unit_q(x):
    n = math.sqrt(sum(c * c for c in x[6:10]))
    return x[:6] + [c / n for c in x[6:10]] + x[10:]


def step(x, s_t, s_r, rate_r, dt=DT):
    """The state after one step of dt seconds (RK4, the inputs held over the step)."""
    x = _unit_q(list(map(float, x)))
    k1 = derivative(x, s_t, s_r, rate_r)
    k2 = derivative(_unit_q([a + 0.5 * dt * b for a, b in zip(x, k1)]), s_t, s_r, rate_r)
    k3 = derivative(_unit_q([a + 0.5 * dt * b for a, b in zip(x, k2)]), s_t, s_r, rate_r)
    k4 = derivative(_unit_q([a + dt * b for a, b in zip(x, k3)]), s_t, s_r, rate_r)
    return _unit_q([a + dt / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)])
'''])


def _vehicle_c(spec: dict, header: list[str], dt_s: float) -> str:
    M, P = spec["M"], spec["P"]
    D = max(spec["d_t"], spec["d_r"]) + 1
    rows = ", ".join("{" + ", ".join(_f(v) for v in P[k]) + "}" for k in range(3))
    lp, ce = _alpha(spec["lp"], dt_s), _alpha(spec["centre"], dt_s)
    lines = ["/*"] + [(" * " + h).rstrip() for h in header] + [
        " *", " * C99; compile with -lm. Usage: droneid_inputs c; droneid_inputs_init(&c); per step:",
        " * droneid_inputs_push(&c, rpm, s_t, s_r, rate_r); droneid_step(x, s_t, s_r, rate_r, DRONEID_DT);", " */"]
    lines.append(f'''#include <math.h>
#include <string.h>

#define DRONEID_M {M}
#define DRONEID_DT {_f(dt_s)}
#define DRONEID_HIST {D}

static const double SCALE = {_f(spec["scale"])};
static const int DELAY_T = {spec["d_t"]}, DELAY_R = {spec["d_r"]};
static const int HAS_LOWPASS = {0 if spec["lp"] is None else 1}, HAS_CENTRE = {0 if spec["centre"] is None else 1}, HAS_BALANCE = {0 if spec["bw"] is None else 1};
static const double LOWPASS_A = {"0.0" if lp == "None" else lp}, CENTRE_A = {"0.0" if ce == "None" else ce};
static const double BALANCE_W = {"0.0" if spec["bw"] is None else _f(spec["bw"])};
static const double PRIOR[DRONEID_M] = {{{", ".join(_f(v) for v in spec["prior"])}}};
static const double P[3][DRONEID_M] = {{{rows}}};
static const double K_T = {_f(spec["k_T"])}, G = {_f(spec["g"])};
static const double DRAG[3] = {{{", ".join(_f(v) for v in spec["drag"])}}};

typedef struct {{
    int started;
    double hist[DRONEID_HIST][DRONEID_M];
    double lp[DRONEID_M], ema[DRONEID_M], prev[DRONEID_M], sum[DRONEID_M];
    double t, dt;
}} droneid_inputs;

void droneid_inputs_init(droneid_inputs *c, double dt)
{{
    memset(c, 0, sizeof *c);
    c->dt = dt;
}}

/* rpm: this step's motor speeds as logged -> s_t, s_r, rate_r (DRONEID_M each) */
void droneid_inputs_push(droneid_inputs *c, const double rpm[DRONEID_M], double s_t[DRONEID_M],
                         double s_r[DRONEID_M], double rate_r[DRONEID_M])
{{
    int i, h;
    double om[DRONEID_M];
    if (!c->started)
        for (h = 0; h < DRONEID_HIST; h++)
            for (i = 0; i < DRONEID_M; i++) c->hist[h][i] = rpm[i] * SCALE;
    for (h = 0; h + 1 < DRONEID_HIST; h++) memcpy(c->hist[h], c->hist[h + 1], sizeof c->hist[h]);
    for (i = 0; i < DRONEID_M; i++) c->hist[DRONEID_HIST - 1][i] = rpm[i] * SCALE;
    for (i = 0; i < DRONEID_M; i++) {{
        double o = c->hist[DRONEID_HIST - 1 - DELAY_T][i];
        s_t[i] = o * o;
        om[i] = c->hist[DRONEID_HIST - 1 - DELAY_R][i];
        if (HAS_LOWPASS) {{
            c->lp[i] = c->started ? LOWPASS_A * om[i] + (1.0 - LOWPASS_A) * c->lp[i] : om[i];
            om[i] = c->lp[i];
        }}
        rate_r[i] = c->started ? (om[i] - c->prev[i]) / c->dt : 0.0;
        c->prev[i] = om[i];
        s_r[i] = om[i] * om[i];
        if (HAS_CENTRE) {{
            c->ema[i] = c->started ? CENTRE_A * s_r[i] + (1.0 - CENTRE_A) * c->ema[i] : s_r[i];
            s_r[i] -= c->ema[i];
        }}
    }}
    if (HAS_BALANCE) {{
        c->t += c->dt;
        for (i = 0; i < DRONEID_M; i++) {{
            c->sum[i] += s_r[i] * c->dt;
            s_r[i] -= (c->sum[i] + BALANCE_W * PRIOR[i]) / (c->t + BALANCE_W);
        }}
    }}
    c->started = 1;
}}

static void rotation_matrix(const double *q, double R[3][3])
{{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    R[0][0] = 1 - 2 * (y * y + z * z); R[0][1] = 2 * (x * y - w * z); R[0][2] = 2 * (x * z + w * y);
    R[1][0] = 2 * (x * y + w * z); R[1][1] = 1 - 2 * (x * x + z * z); R[1][2] = 2 * (y * z - w * x);
    R[2][0] = 2 * (x * z - w * y); R[2][1] = 2 * (y * z + w * x); R[2][2] = 1 - 2 * (x * x + y * y);
}}

void droneid_derivative(const double x[13], const double s_t[DRONEID_M], const double s_r[DRONEID_M],
                        const double rate_r[DRONEID_M], double dx[13])
{{
    double R[3][3], vb[3], mix[3], S = 0.0, spin = 0.0, thrust = 0.0;
    const double *v = x + 3, *w = x + 10;
    int i, j, k;
    rotation_matrix(x + 6, R);
    for (j = 0; j < 3; j++) {{ vb[j] = 0.0; for (i = 0; i < 3; i++) vb[j] += R[i][j] * v[i]; }}
    for (i = 0; i < DRONEID_M; i++) {{ thrust += s_t[i]; S += s_r[i]; spin += P[2][i] * rate_r[i]; }}
    thrust *= K_T;
    for (k = 0; k < 3; k++) {{ mix[k] = 0.0; for (i = 0; i < DRONEID_M; i++) mix[k] += P[k][i] * s_r[i]; }}
    for (i = 0; i < 3; i++) {{
        dx[i] = v[i];
        dx[3 + i] = R[i][2] * thrust;
        for (j = 0; j < 3; j++) dx[3 + i] -= R[i][j] * DRAG[j] * vb[j];
    }}
    dx[5] -= G;
    dx[6] = 0.5 * (-x[7] * w[0] - x[8] * w[1] - x[9] * w[2]);
    dx[7] = 0.5 * (x[6] * w[0] + x[8] * w[2] - x[9] * w[1]);
    dx[8] = 0.5 * (x[6] * w[1] - x[7] * w[2] + x[9] * w[0]);
    dx[9] = 0.5 * (x[6] * w[2] + x[7] * w[1] - x[8] * w[0]);
    dx[10] = {_axis_expr(spec, 0)};
    dx[11] = {_axis_expr(spec, 1)};
    dx[12] = {_axis_expr(spec, 2)};
    (void)S; (void)spin; (void)vb;
}}

static void unit_q(double *x)
{{
    double n = sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9]);
    int i;
    for (i = 6; i < 10; i++) x[i] /= n;
}}

/* x (13) advanced by one RK4 step of dt seconds, the inputs held over the step */
void droneid_step(double x[13], const double s_t[DRONEID_M], const double s_r[DRONEID_M],
                  const double rate_r[DRONEID_M], double dt)
{{
    double k1[13], k2[13], k3[13], k4[13], y[13];
    int i;
    unit_q(x);
    droneid_derivative(x, s_t, s_r, rate_r, k1);
    for (i = 0; i < 13; i++) y[i] = x[i] + 0.5 * dt * k1[i];
    unit_q(y);
    droneid_derivative(y, s_t, s_r, rate_r, k2);
    for (i = 0; i < 13; i++) y[i] = x[i] + 0.5 * dt * k2[i];
    unit_q(y);
    droneid_derivative(y, s_t, s_r, rate_r, k3);
    for (i = 0; i < 13; i++) y[i] = x[i] + dt * k3[i];
    unit_q(y);
    droneid_derivative(y, s_t, s_r, rate_r, k4);
    for (i = 0; i < 13; i++) x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    unit_q(x);
}}
''')
    return "\n".join(lines)
