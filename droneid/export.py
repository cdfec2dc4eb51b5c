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

``export_vehicle(translation, rotation, to)`` returns the whole vehicle (issue 28) as one Python or
C file: a step function of the 13-element state and the logged motor speeds. The translation is
identify's final v̇ models (their own expressions, generated as above, fed the simulated velocity
and Euler angles) or the library's :class:`droneid.rotation.TranslationModel`; the rotation a
:class:`droneid.rotation.RotationModel` or None (body rates held). It steps as
:func:`droneid.openloop.simulate` steps ``IdentifiedVehicle`` (``droneid export --vehicle``).
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from . import __version__
from .errors import ConfigError, MissingSignalError, check_choice
from .expressions import round_expr
from .flight import canonical_unit
from .closed_form import IdentifiedModel
from .rotation import _SPEED_UNIT, RotationModel, TranslationModel
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
    out = ['"""' + "\n".join(header).replace('"""', "'''").replace("\\", "\\\\") + '\n"""', "import numpy", ""]
    out += _python_defs(models, sources)
    return "\n".join(out).rstrip() + "\n"


def _python_defs(models, sources) -> list[str]:
    """One keyword-only function per model (``numpy`` imported by the caller)."""
    from sympy.printing.numpy import NumPyPrinter
    out = []
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
    return out


def _c(models, header) -> str:
    out = ["/*"] + [(" * " + h).rstrip() for h in header] + [
        " *", " * C99; compile with -lm. Arguments in alphabetical order of the signal names.", " */",
        "#include <math.h>", ""]
    return "\n".join(out + _c_defs(models))


def _c_defs(models) -> list[str]:
    """One C99 function per model, the signals as arguments in alphabetical order."""
    out = []
    for m in models:
        args = ", ".join(f"double {s}" for s in m.signals) or "void"
        out += [f"/* {m.target} in {m.unit} */", f"double {m.target}({args})", "{",
                f"    return {sp.ccode(m.expr, standard='C99')};", "}", ""]
    return out


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
_TRANSLATION_TARGETS = ("vx_dot", "vy_dot", "vz_dot")
#: the state the v̇ models read, as an expression of the generated derivative (Python and C alike)
_STATE_ARGS = {"vx": "x[3]", "vy": "x[4]", "vz": "x[5]", "roll": "roll", "pitch": "pitch", "yaw": "yaw"}


def _f(x) -> str:
    return repr(float(x))


def _floats(values, to: str) -> str:
    """Floats as a Python list or a C initializer."""
    body = ", ".join(_f(v) for v in values)
    return f"[{body}]" if to == "python" else f"{{{body}}}"


@dataclass(frozen=True)
class _Part:
    """One half of a generated vehicle (translation or rotation).

    ``header``: its lines of the file header; ``width``: the input columns it reads from ``u``
    (after those of the parts before it); ``history``: how many steps back it reads the motor
    speeds (its largest delay); ``code[to]``: source snippets in language ``to``: ``defs``
    (module level), ``state`` (Python: lines of ``Inputs.__init__``; C: members of the
    ``droneid_inputs`` struct), ``fill`` (in the conditioner, after the motor speeds of this step
    joined the history ``h``, oldest first: its columns of ``u``) and ``deriv`` (in the
    derivative: v̇ or ω̇ from ``x``, ``R``, ``vb`` and its columns of ``u``); ``euler``: it reads
    ``roll``, ``pitch``, ``yaw`` of the simulated quaternion (the derivative then computes them)."""
    header: tuple
    width: int
    history: int
    code: Mapping
    imports: tuple = ()
    euler: bool = False


def _rotation_spec(rotation: RotationModel) -> dict:
    """Constants of a :class:`droneid.rotation.RotationModel`, checked for export: ``cols[k]`` are
    axis ``k``'s columns as expressions of the generated derivative (:func:`_column_code`)."""
    cols = [[_column_code(name, k) for name in rotation.columns(k)] for k in range(3)]
    for k in range(3):
        if len(cols[k]) != np.asarray(rotation.coef[k]).size:
            raise ConfigError(f"export_vehicle: axis {k} has {np.asarray(rotation.coef[k]).size} coefficients for "
                              f"{len(cols[k])} columns")
    level = getattr(rotation, "level_rad", None)
    return {"M": rotation.layout.motors, "P": rotation.layout.patterns(),
            "scale": rotation.rad_s_per_rpm / _SPEED_UNIT, "d_r": int(rotation.delay_steps),
            "lp": rotation.lowpass_tau_s, "centre": rotation.centre_tau_s, "bw": rotation.balance_weight_s,
            "prior": (np.zeros(rotation.layout.motors) if rotation.balance_prior is None
                      else np.asarray(rotation.balance_prior, float)),
            "cols": cols, "coef": [np.asarray(c, float) for c in rotation.coef],
            "trim": np.asarray(rotation.trim, float), "layout": rotation.layout.name,
            "level": np.zeros(2) if level is None else np.asarray(level, float),
            "euler": any("attitude" in rotation.columns(k) for k in range(3))}


def _column_code(name: str, k: int) -> str:
    """Column ``name`` of axis ``k`` (:meth:`droneid.rotation.RotationModel.columns`) in the
    generated derivative, C and Python alike: ``mix[k]`` = (P s_r)_k, ``S`` = Σ s_r, ``w[]`` body
    rates, ``vb[]`` body velocity, ``spin`` = yaw pattern · rate_r, ``roll``/``pitch`` (rad) and
    ``LEVEL[]`` the level attitude."""
    i, j = [(1, 2), (2, 0), (0, 1)][k]
    code = {"pattern": f"mix[{k}]", "centre": "S", "damping": f"(-w[{k}])", "gyro": f"w[{i}]*w[{j}]",
            "spinup": "spin"}
    if k < 2:
        jv, sign = ((1, "+"), (0, "-"))[k]
        code.update({"rotor_drag": f"({sign}vb[{jv}])", "rotor_drag_thrust": f"({sign}vb[{jv}]*S)",
                     "attitude": f"(-({('roll', 'pitch')[k]} - LEVEL[{k}]))"})
    if name not in code:
        raise ConfigError(f"export_vehicle: the rotational term {name!r} of axis {k} cannot be written "
                          f"(known: {', '.join(code)})")
    return code[name]


def _axis_expr(spec: dict, k: int) -> str:
    """ω̇_k as an expression of the generated derivative (C and Python alike)."""
    return " + ".join([f"({_f(ci)})*{col}" for ci, col in zip(spec["coef"][k], spec["cols"][k])]
                      + [f"({_f(spec['trim'][k])})"])


def _alpha(tau, dt_s: float) -> str:
    return "None" if tau is None else _f(min(1.0, dt_s / float(tau)))


def _rotation_part(rotation: RotationModel, offset: int, dt_s: float) -> _Part:
    """The rotational model: its input conditioning (delay, low-pass, rotor speed rates, centring,
    running balance) and ω̇ per axis; its columns ``u[offset:offset + 2M]`` are ``s_r`` then the
    rotor speed rates."""
    spec = _rotation_spec(rotation)
    M, P, o = spec["M"], spec["P"], offset
    lp, ce = _alpha(spec["lp"], dt_s), _alpha(spec["centre"], dt_s)
    bw = "None" if spec["bw"] is None else _f(spec["bw"])
    steps = [f"the motor speeds of {spec['d_r']} step(s) earlier as rotor speeds (rpm * "
             f"{_f(rotation.rad_s_per_rpm)} rad/s)"]
    if spec["lp"] is not None:
        steps.append(f"low-passed (first order, time constant {spec['lp']:g} s)")
    steps.append("squared as (rotor speed / 1000 rad/s)^2")
    if spec["centre"] is not None:
        steps.append(f"taken about their moving average (time constant {spec['centre']:g} s)")
    if spec["bw"] is not None:
        steps.append(f"balanced about their mean since the first step (the training mean weighted as {spec['bw']:g} s)")
    header = (
        f"Rotation (rad/s^2, body FLU), rotor layout {spec['layout']}: u[{o}:{o + M}] = s_r, u[{o + M}:{o + 2 * M}] = rate_r:",
        *(f"  {'s_r: ' if i == 0 else '  then '}{t}" for i, t in enumerate(steps)),
        "  rate_r: the rate of the (low-passed) rotor speeds, (rad/s)/s, backward difference over one step.",
        "  w'_k = coefficients . columns + trim; mix = P s_r (roll, pitch, yaw patterns of the layout),",
        "  S = sum(s_r), vb = R^T v (body velocity, m/s), spin = yaw pattern . rate_r"
        + (f", roll and pitch (rad, Z-Y-X, of the simulated quaternion) about the level LEVEL = "
           f"{', '.join(_f(v) for v in spec['level'])} rad:" if spec["euler"] else ":"),
        *[f"  w'_{k} = {_axis_expr(spec, k)}" for k in range(3)])
    py_defs = f'''SCALE_R = {_f(spec["scale"])}          # (rotor speed / 1000 rad/s) per logged rpm
DELAY_R = {spec["d_r"]}
LOWPASS_A = {lp}
CENTRE_A = {ce}
BALANCE_W = {bw}
PRIOR = {_floats(spec["prior"], "python")}
P = [{", ".join(_floats(P[k], "python") for k in range(3))}]
LEVEL = {_floats(spec["level"], "python")}          # level roll, pitch (rad) of the term attitude
'''
    py_state = '''        self.lp = self.ema = self.prev = None
        self.sum = [0.0] * M
        self.t = 0.0
'''
    py_fill = '''        om = [r * SCALE_R for r in h[-1 - DELAY_R]]
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
        u += s + rate
'''
    py_deriv = f'''    s_r, rate_r = u[{o}:{o + M}], u[{o + M}:{o + 2 * M}]
    mix = [sum(P[k][i] * s_r[i] for i in range(M)) for k in range(3)]
    S = sum(s_r)
    spin = sum(P[2][i] * rate_r[i] for i in range(M))
    dw = [{_axis_expr(spec, 0)},
          {_axis_expr(spec, 1)},
          {_axis_expr(spec, 2)}]
'''
    c_defs = f'''static const double SCALE_R = {_f(spec["scale"])};
static const int DELAY_R = {spec["d_r"]};
static const int HAS_LOWPASS = {0 if spec["lp"] is None else 1}, HAS_CENTRE = {0 if spec["centre"] is None else 1}, HAS_BALANCE = {0 if spec["bw"] is None else 1};
static const double LOWPASS_A = {"0.0" if lp == "None" else lp}, CENTRE_A = {"0.0" if ce == "None" else ce};
static const double BALANCE_W = {"0.0" if spec["bw"] is None else _f(spec["bw"])};
static const double PRIOR[DRONEID_M] = {_floats(spec["prior"], "c")};
static const double P[3][DRONEID_M] = {{{", ".join(_floats(P[k], "c") for k in range(3))}}};
static const double LEVEL[2] = {_floats(spec["level"], "c")};
'''
    c_state = "    double lp[DRONEID_M], ema[DRONEID_M], prev[DRONEID_M], sum[DRONEID_M], t;\n"
    c_fill = f'''    {{
        double *s_r = u + {o}, *rate_r = u + {o + M}, om;
        for (i = 0; i < DRONEID_M; i++) {{
            om = c->hist[DRONEID_HIST - 1 - DELAY_R][i] * SCALE_R;
            if (HAS_LOWPASS) {{
                c->lp[i] = c->started ? LOWPASS_A * om + (1.0 - LOWPASS_A) * c->lp[i] : om;
                om = c->lp[i];
            }}
            rate_r[i] = c->started ? (om - c->prev[i]) / c->dt : 0.0;
            c->prev[i] = om;
            s_r[i] = om * om;
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
    }}
'''
    c_deriv = f'''    {{
        const double *s_r = u + {o}, *rate_r = u + {o + M};
        double mix[3], S = 0.0, spin = 0.0;
        int k;
        for (i = 0; i < DRONEID_M; i++) {{ S += s_r[i]; spin += P[2][i] * rate_r[i]; }}
        for (k = 0; k < 3; k++) {{ mix[k] = 0.0; for (i = 0; i < DRONEID_M; i++) mix[k] += P[k][i] * s_r[i]; }}
        dx[10] = {_axis_expr(spec, 0)};
        dx[11] = {_axis_expr(spec, 1)};
        dx[12] = {_axis_expr(spec, 2)};
        (void)S; (void)spin; (void)LEVEL;
    }}
'''
    return _Part(header, 2 * M, spec["d_r"], {
        "python": {"defs": py_defs, "state": py_state, "fill": py_fill, "deriv": py_deriv},
        "c": {"defs": c_defs, "state": c_state, "fill": c_fill, "deriv": c_deriv}}, euler=spec["euler"])


def _held_rates_part() -> _Part:
    """No rotational model: every body rate held (ω̇ = 0), no input columns."""
    return _Part(("Rotation: none identified (the result's rotation.model is null): every body rate is held, "
                  "w' = 0.",), 0, 0, {
        "python": {"defs": "", "state": "", "fill": "", "deriv": "    dw = [0.0, 0.0, 0.0]\n"},
        "c": {"defs": "", "state": "", "fill": "", "deriv": "    dx[10] = dx[11] = dx[12] = 0.0;\n"}})


def _linear_part(tr: TranslationModel, motors: int) -> _Part:
    """:class:`droneid.rotation.TranslationModel`: thrust along body z, body drag, gravity;
    columns ``u[0:M]`` are ``s_t``."""
    scale, d = tr.rad_s_per_rpm / _SPEED_UNIT, int(tr.delay_steps)
    header = (
        "Translation (m/s^2, world ENU): v' = R e_z k_T sum(s_t) - R diag(drag) R^T v - g e_z;",
        f"  k_T = {_f(tr.k_thrust)} m/s^2, drag = {', '.join(_f(v) for v in tr.drag)} 1/s, g = {_f(tr.g)};",
        f"  u[0:{motors}] = s_t: (rpm * {_f(scale)})^2, i.e. (rotor speed / 1000 rad/s)^2, of the motor speeds "
        f"{d} step(s) earlier.")
    py_defs = f'''SCALE_T = {_f(scale)}          # (rotor speed / 1000 rad/s) per logged rpm
DELAY_T = {d}
K_T, G = {_f(tr.k_thrust)}, {_f(tr.g)}
DRAG = {_floats(tr.drag, "python")}
'''
    py_fill = "        u += [o * o for o in (r * SCALE_T for r in h[-1 - DELAY_T])]\n"
    py_deriv = f'''    thrust = K_T * sum(u[0:{motors}])
    dv = [R[i][2] * thrust - sum(R[i][j] * DRAG[j] * vb[j] for j in range(3)) for i in range(3)]
    dv[2] -= G
'''
    c_defs = f'''static const double SCALE_T = {_f(scale)};
static const int DELAY_T = {d};
static const double K_T = {_f(tr.k_thrust)}, G = {_f(tr.g)};
static const double DRAG[3] = {_floats(tr.drag, "c")};
'''
    c_fill = '''    for (i = 0; i < DRONEID_M; i++) {
        double o = c->hist[DRONEID_HIST - 1 - DELAY_T][i] * SCALE_T;
        u[i] = o * o;
    }
'''
    c_deriv = '''    {
        double thrust = 0.0;
        for (i = 0; i < DRONEID_M; i++) thrust += u[i];
        thrust *= K_T;
        for (i = 0; i < 3; i++) {
            dx[3 + i] = R[i][2] * thrust;
            for (j = 0; j < 3; j++) dx[3 + i] -= R[i][j] * DRAG[j] * vb[j];
        }
        dx[5] -= G;
    }
'''
    return _Part(header, motors, d, {
        "python": {"defs": py_defs, "state": "", "fill": py_fill, "deriv": py_deriv},
        "c": {"defs": c_defs, "state": "", "fill": c_fill, "deriv": c_deriv}})


def _rpm_index(name: str) -> int:
    return int(name[3:]) - 1


def _identified_part(models: Mapping, dt_s: float, source: str, sources: dict, to: str) -> tuple[_Part, int]:
    """identify's final v̇ models (:class:`droneid.openloop.IdentifiedTranslation`), fed the simulated
    velocity and Euler angles and their motor speeds at ``t − delay`` in whole steps of ``dt_s``,
    as :meth:`IdentifiedTranslation.inputs` reads them; columns model by model, motor by motor.
    Returns the part and the highest motor number the models read."""
    from .openloop import IdentifiedTranslation
    missing = [t for t in _TRANSLATION_TARGETS if t not in models]
    if missing:
        raise ConfigError(f"the whole vehicle needs final models of vx_dot, vy_dot and vz_dot; "
                          f"missing: {', '.join(missing)}")
    tr = IdentifiedTranslation({t: models[t] for t in _TRANSLATION_TARGETS})   # refuses other signals
    ordered = _check([tr.models[t] for t in _TRANSLATION_TARGETS])
    names = tr._rpm_names()
    steps, notes = {}, []
    for m in ordered:
        for s, d in sorted(m.delays_s.items()):
            if s not in names:
                notes.append(f"  {m.target}: the delay of {s} ({d:g} s) is not applied: the simulated state is "
                             "read at t (as droneid.openloop does)")
        for name in names:
            d = float(m.delays_s.get(name, 0.0))
            k = int(round(d / dt_s))
            if k < 0:
                raise ConfigError(f"cannot export the vehicle: the {m.target} model reads {name} {-d:g} s ahead "
                                  f"(a negative delay); a step function fed one step at a time cannot read ahead")
            if abs(d / dt_s - k) > 1e-6:
                notes.append(f"  {m.target}: the delay of {name} ({d:g} s) is rounded to {k} step(s) of {dt_s:g} s "
                             "(as droneid.openloop does)")
            steps[m.target, name] = k
    K = len(names)
    col = {(a, name): a * K + i for a in range(3) for i, name in enumerate(names)}
    equations = _header(ordered, source, to, sources)[3:]     # in the syntax of the file's language
    header = ("Translation (m/s^2, world ENU): identify's final models, fed the simulated velocity vx, vy, vz "
              "and the Z-Y-X Euler angles",
              "  roll, pitch, yaw of the simulated quaternion (pitch clipped to [-pi/2, pi/2]):",
              *("  " + line for line in equations), *notes,
              f"  u[0:{3 * K}]: the logged motor speeds each model reads, at their delays in whole steps:",
              *(f"    u[{a * K}:{(a + 1) * K}] ({m.target}): "
                + ", ".join(f"{n} of {steps[m.target, n]} step(s) earlier" for n in names)
                for a, m in enumerate(ordered) if names))
    langs = {"python": lambda m, n: f"h[-1 - {steps[m.target, n]}][{_rpm_index(n)}]",
             "c": lambda m, n: f"c->hist[DRONEID_HIST - 1 - {steps[m.target, n]}][{_rpm_index(n)}]"}
    py_fill = "        u += [" + ", ".join(langs["python"](m, n) for m in ordered for n in names) + "]\n"
    c_fill = "".join(f"    u[{col[a, n]}] = {langs['c'](m, n)};\n" for a, m in enumerate(ordered) for n in names)

    def args(a, m, to):
        vals = [_STATE_ARGS[s] if s in _STATE_ARGS else f"u[{col[a, s]}]" for s in m.signals]
        return ", ".join(f"{s}={v}" for s, v in zip(m.signals, vals)) if to == "python" else ", ".join(vals)

    py_defs = "\n".join(_python_defs(ordered, sources)).strip() + "\n"
    py_deriv = ("    dv = ["
                + ",\n          ".join(f"float({m.target}({args(a, m, 'python')}))" for a, m in enumerate(ordered))
                + "]\n")
    c_defs = "\n".join(_c_defs(ordered))
    c_deriv = "".join(f"    dx[{3 + a}] = {m.target}({args(a, m, 'c')});\n" for a, m in enumerate(ordered))
    part = _Part(header, 3 * K, max(steps.values(), default=0), {
        "python": {"defs": py_defs, "state": "", "fill": py_fill, "deriv": py_deriv},
        "c": {"defs": c_defs, "state": "", "fill": c_fill, "deriv": c_deriv}}, imports=("numpy",), euler=True)
    return part, max((_rpm_index(n) + 1 for n in names), default=0)


def export_vehicle(translation, rotation, to: str, source: str = "", dt_s: float = 0.01, *,
                   inputs: dict | None = None, dt_note: str = "") -> str:
    """The text of one file with the full 6-DOF model in ``to`` (``"python"`` or ``"c"``).

    ``translation``: a :class:`droneid.rotation.TranslationModel`, or identify's final v̇ models
    (``{"vx_dot", "vy_dot", "vz_dot": IdentifiedModel}`` or a
    :class:`droneid.openloop.IdentifiedTranslation`); ``rotation``: a
    :class:`droneid.rotation.RotationModel`, or None for the body rates held (ω̇ = 0).
    ``dt_s``: the step (s) the motor speeds are fed at: the delays and the rotational model's
    conditioning are in steps of it, so it must be the grid the models were identified on;
    ``dt_note`` says in the header where it came from; ``inputs``: :func:`input_sources` for the
    header.

    The file holds an input conditioner (the logged motor speeds -> the model's inputs ``u``,
    causal, one step at a time: delays, and for the rotation low-pass, rotor speed rates,
    centring, running balance), the state derivative and one RK4 step with the quaternion
    renormalised at every stage (as :func:`droneid.openloop.simulate`). Python:
    ``Inputs().push(rpm) -> u``, ``step(x, u, dt=DT) -> x``; C99: ``droneid_inputs_init``,
    ``droneid_inputs_push(&c, rpm, u)``, ``droneid_step(x, u, dt)`` (compile with -lm).
    """
    if to not in VEHICLE_FORMATS:
        check_choice("to", to, VEHICLE_FORMATS, owner="export_vehicle")
    if not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s) and dt_s > 0):
        raise ConfigError(f"The 'dt_s' parameter of export_vehicle must be a positive number of seconds. "
                          f"Got {dt_s!r} instead.")
    if rotation is not None and not isinstance(rotation, RotationModel):
        raise ConfigError("export_vehicle needs a droneid.rotation.RotationModel or None (rates held); "
                          f"got {type(rotation).__name__}")
    if isinstance(translation, TranslationModel):
        if rotation is None:
            raise ConfigError("export_vehicle: a TranslationModel needs a RotationModel (the rotor layout "
                              "says how many motors it reads)")
        if translation.rad_s_per_rpm != rotation.rad_s_per_rpm:
            raise ConfigError("export_vehicle: the translation and the rotation read the motor speeds in "
                              "different units (rad_s_per_rpm)")
        motors = rotation.layout.motors
        tpart = _linear_part(translation, motors)
    elif isinstance(translation, Mapping) or hasattr(translation, "models"):
        models = translation if isinstance(translation, Mapping) else translation.models
        tpart, read = _identified_part(models, float(dt_s), source, inputs or {}, to)
        motors = rotation.layout.motors if rotation is not None else max(read, 1)
        if read > motors:
            raise ConfigError(f"export_vehicle: the v̇ models read rpm{read}; the rotor layout has {motors} rotors")
    else:
        raise ConfigError("export_vehicle needs a droneid.rotation.TranslationModel or identify's final v̇ "
                          f"models; got {type(translation).__name__}")
    rpart = _held_rates_part() if rotation is None else _rotation_part(rotation, tpart.width, float(dt_s))
    unit = _input_unit("rpm1", inputs or {})
    width = tpart.width + rpart.width
    header = [
        f"droneid {__version__}: the whole vehicle (6-DOF), stepped open loop from motor speeds.",
        f"Source: {source or 'droneid models'}.",
        "Conventions: " + CONVENTIONS + ".",
        "State x[13]: p (m, world ENU) 0:3, v (m/s, world ENU) 3:6, q (qw, qx, qy, qz; Hamilton, FLU body",
        "to ENU world, unit norm) 6:10, w (rad/s, body FLU) 10:13.",
        f"Step: dt = {_f(dt_s)} s{f' ({dt_note})' if dt_note else ''}; every delay below is in steps of dt.",
        f"Inputs: the {motors} logged motor speeds rpm[{motors}] ({unit}) of each step, fed in order from the "
        "start of the flight",
        f"to the input conditioner, which returns u[{width}], held over that step:",
        *tpart.header, *rpart.header,
        "Integration: classical RK4, the quaternion renormalised at every stage and after the step",
        "(as droneid.openloop.simulate)."]
    build = _vehicle_python if to == "python" else _vehicle_c
    return build([tpart, rpart], header, motors, width, float(dt_s))


_PY_EULER = '''def _euler(q):
    """Z-Y-X (roll, pitch, yaw) in rad of the quaternion q (normalised first; pitch clipped at gimbal
    lock), as droneid.frames.quat_to_euler."""
    n = math.sqrt(sum(c * c for c in q))
    w, x, y, z = (c / n for c in q)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(min(1.0, max(-1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


'''

_C_EULER = '''/* Z-Y-X roll, pitch, yaw (rad) of the quaternion q (normalised first; pitch clipped at gimbal lock) */
static void droneid_euler(const double *q, double *roll, double *pitch, double *yaw)
{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    double sp = 2.0 * (w * y - z * x);
    *roll = atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y));
    *pitch = asin(sp < -1.0 ? -1.0 : (sp > 1.0 ? 1.0 : sp));
    *yaw = atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
}

'''


def _vehicle_python(parts, header, M: int, width: int, dt_s: float) -> str:
    imports = sorted({"math", *(i for p in parts for i in p.imports)})
    euler = any(p.euler for p in parts)
    code = [p.code["python"] for p in parts]
    return '\n'.join(['"""' + "\n".join(header).replace('"""', "'''").replace("\\", "\\\\") + "\n\nUsage: "
                      "inputs = Inputs() (one per flight); per step: x = step(x, inputs.push(rpm)).\n"
                      '"""', *(f"import {i}" for i in imports), f'''
M = {M}
DT = {_f(dt_s)}
U = {width}
HIST = {max(p.history for p in parts) + 1}
''' + "".join("\n\n" + c["defs"].strip() + "\n" for c in code if c["defs"]) + f'''

class Inputs:
    """The logged motor speeds to the model's inputs u, one step at a time (causal)."""

    def __init__(self, dt=DT):
        self.dt = dt
        self.hist = None
{"".join(c["state"] for c in code)}
    def push(self, rpm):
        """rpm: the M motor speeds of this step as logged -> u (list of U), held over the step."""
        now = [float(r) for r in rpm]
        if len(now) != M:
            raise ValueError(f"push takes the {{M}} motor speeds of one step, got {{len(now)}}")
        if self.hist is None:
            self.hist = [now] * HIST
        self.hist = self.hist[1:] + [now]
        h = self.hist
        u = []
{"".join(c["fill"] for c in code)}        return u


{_PY_EULER if euler else ""}def _rot(q):
    n = math.sqrt(sum(c * c for c in q))
    w, x, y, z = (c / n for c in q)
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def derivative(x, u):
    """dx/dt (list of 13) of the state x (13) with the inputs u (U) of this step."""
    R = _rot(x[6:10])
    v, w = x[3:6], x[10:13]
    vb = [sum(R[i][j] * v[i] for i in range(3)) for j in range(3)]
{"    roll, pitch, yaw = _euler(x[6:10])" + chr(10) if euler else ""}{"".join(c["deriv"] for c in code)}    qw, qx, qy, qz = x[6:10]
    dq = [0.5 * (-qx * w[0] - qy * w[1] - qz * w[2]), 0.5 * (qw * w[0] + qy * w[2] - qz * w[1]),
          0.5 * (qw * w[1] - qx * w[2] + qz * w[0]), 0.5 * (qw * w[2] + qx * w[1] - qy * w[0])]
    return list(v) + dv + dq + dw


def _unit_q(x):
    n = math.sqrt(sum(c * c for c in x[6:10]))
    return x[:6] + [c / n for c in x[6:10]] + x[10:]


def step(x, u, dt=DT):
    """The state after one step of dt seconds (RK4, the inputs u held over the step)."""
    x = _unit_q(list(map(float, x)))
    k1 = derivative(x, u)
    k2 = derivative(_unit_q([a + 0.5 * dt * b for a, b in zip(x, k1)]), u)
    k3 = derivative(_unit_q([a + 0.5 * dt * b for a, b in zip(x, k2)]), u)
    k4 = derivative(_unit_q([a + dt * b for a, b in zip(x, k3)]), u)
    return _unit_q([a + dt / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)])
'''])


def _vehicle_c(parts, header, M: int, width: int, dt_s: float) -> str:
    code = [p.code["c"] for p in parts]
    euler = any(p.euler for p in parts)
    lines = ["/*"] + [(" * " + h).rstrip() for h in header] + [
        " *", " * C99; compile with -lm. Usage: droneid_inputs c; droneid_inputs_init(&c, DRONEID_DT); per step:",
        " * droneid_inputs_push(&c, rpm, u); droneid_step(x, u, DRONEID_DT); with double u[DRONEID_U].", " */"]
    lines.append(f'''#include <math.h>
#include <string.h>

#define DRONEID_M {M}
#define DRONEID_U {max(width, 1)}
#define DRONEID_DT {_f(dt_s)}
#define DRONEID_HIST {max(p.history for p in parts) + 1}

''' + "".join(c["defs"] + "\n" for c in code if c["defs"]) + f'''typedef struct {{
    int started;
    double hist[DRONEID_HIST][DRONEID_M];
{"".join(c["state"] for c in code)}    double dt;
}} droneid_inputs;

void droneid_inputs_init(droneid_inputs *c, double dt)
{{
    memset(c, 0, sizeof *c);
    c->dt = dt;
}}

/* rpm: this step's DRONEID_M motor speeds as logged -> u (DRONEID_U), held over the step */
void droneid_inputs_push(droneid_inputs *c, const double rpm[DRONEID_M], double u[DRONEID_U])
{{
    int i, h;
    if (!c->started)
        for (h = 0; h < DRONEID_HIST; h++)
            for (i = 0; i < DRONEID_M; i++) c->hist[h][i] = rpm[i];
    for (h = 0; h + 1 < DRONEID_HIST; h++) memcpy(c->hist[h], c->hist[h + 1], sizeof c->hist[h]);
    for (i = 0; i < DRONEID_M; i++) c->hist[DRONEID_HIST - 1][i] = rpm[i];
{"".join(c["fill"] for c in code)}    c->started = 1;
    (void)u;
}}

{_C_EULER if euler else ""}static void rotation_matrix(const double *q, double R[3][3])
{{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    R[0][0] = 1 - 2 * (y * y + z * z); R[0][1] = 2 * (x * y - w * z); R[0][2] = 2 * (x * z + w * y);
    R[1][0] = 2 * (x * y + w * z); R[1][1] = 1 - 2 * (x * x + z * z); R[1][2] = 2 * (y * z - w * x);
    R[2][0] = 2 * (x * z - w * y); R[2][1] = 2 * (y * z + w * x); R[2][2] = 1 - 2 * (x * x + y * y);
}}

void droneid_derivative(const double x[13], const double u[DRONEID_U], double dx[13])
{{
    double R[3][3], vb[3];
    const double *v = x + 3, *w = x + 10;
    int i, j;
    rotation_matrix(x + 6, R);
    for (j = 0; j < 3; j++) {{ vb[j] = 0.0; for (i = 0; i < 3; i++) vb[j] += R[i][j] * v[i]; }}
    for (i = 0; i < 3; i++) dx[i] = v[i];
{"    double roll, pitch, yaw;" + chr(10) + "    droneid_euler(x + 6, &roll, &pitch, &yaw);" + chr(10) if euler else ""}{"".join(c["deriv"] for c in code)}    dx[6] = 0.5 * (-x[7] * w[0] - x[8] * w[1] - x[9] * w[2]);
    dx[7] = 0.5 * (x[6] * w[0] + x[8] * w[2] - x[9] * w[1]);
    dx[8] = 0.5 * (x[6] * w[1] - x[7] * w[2] + x[9] * w[0]);
    dx[9] = 0.5 * (x[6] * w[2] + x[7] * w[1] - x[8] * w[0]);
    (void)u; (void)vb;{" (void)roll; (void)pitch; (void)yaw;" if euler else ""}
}}

static void unit_q(double *x)
{{
    double n = sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9]);
    int i;
    for (i = 6; i < 10; i++) x[i] /= n;
}}

/* x (13) advanced by one RK4 step of dt seconds, the inputs u held over the step */
void droneid_step(double x[13], const double u[DRONEID_U], double dt)
{{
    double k1[13], k2[13], k3[13], k4[13], y[13];
    int i;
    unit_q(x);
    droneid_derivative(x, u, k1);
    for (i = 0; i < 13; i++) y[i] = x[i] + 0.5 * dt * k1[i];
    unit_q(y);
    droneid_derivative(y, u, k2);
    for (i = 0; i < 13; i++) y[i] = x[i] + 0.5 * dt * k2[i];
    unit_q(y);
    droneid_derivative(y, u, k3);
    for (i = 0; i < 13; i++) y[i] = x[i] + dt * k3[i];
    unit_q(y);
    droneid_derivative(y, u, k4);
    for (i = 0; i < 13; i++) x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    unit_q(x);
}}
''')
    return "\n".join(lines)
