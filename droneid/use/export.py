"""Export final models (:class:`droneid.fitting.closed_form.IdentifiedModel`) as self-contained code.

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

The whole vehicle (a 6-DOF step function) is written by :mod:`droneid.use.vehicle_export`.
"""
from __future__ import annotations

import re
from collections.abc import Sequence

import sympy as sp

from droneid import __version__
from droneid.errors import ConfigError, MissingSignalError, check_choice
from droneid.core.expressions import c_code, octave_code, round_expr
from droneid.logs.flight import canonical_unit
from droneid.fitting.closed_form import IdentifiedModel
from droneid.core.targets import state_of

__all__ = ["FORMATS", "export_models", "input_sources", "CONVENTIONS", "input_unit", "model_header", "checked_models",
           "python_functions", "c_functions"]

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
        return c_code(e)
    if to == "matlab":
        return octave_code(e)
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


def input_unit(signal: str, sources: dict) -> str:
    """The unit the data of ``signal`` had (as recorded; e.g. erpm), else its canonical unit."""
    units = {u for u, _ in sources.get(signal, ())}
    return units.pop() if len(units) == 1 else _unit(signal)


def _input_line(signal: str, sources: dict) -> str:
    fields = [src for _, src in sources.get(signal, ()) if src]
    return f"{signal} [{input_unit(signal, sources)}]" + (f" from {' | '.join(fields)}" if fields else "")


def model_header(models: Sequence[IdentifiedModel], source: str, to: str = "python",
            sources: dict | None = None, delays_note: str = "") -> list[str]:
    """The header lines (without comment markers); equations in the syntax of ``to``.
    ``delays_note``: said after each model's delays (a vehicle that feeds them otherwise)."""
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
            lines.append("  delays: " + ", ".join(f"feed {s} at t - {d:g} s" for s, d in sorted(m.delays_s.items()))
                         + (f" ({delays_note})" if delays_note else ""))
        else:
            lines.append("  delays: none (every input at time t)")
    return lines


def checked_models(models: Sequence[IdentifiedModel]) -> list[IdentifiedModel]:
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
                  inputs: dict | None = None, notes: Sequence[str] = ()) -> str:
    """The text of one file holding every model, in format ``to`` (one of :data:`FORMATS`).

    ``source`` names where the models come from (e.g. the result.json path) for the header;
    ``name`` is the MATLAB function name (the file must be called ``<name>.m``); ``inputs`` maps
    a signal to its unit, raw log field and normalisation (:func:`input_sources` of the result's
    provenance) for the header; ``notes``: sentences the header states first (which model of a
    target was written, and why)."""
    check_choice("to", to, FORMATS, owner="export")
    models = checked_models(models)
    header = model_header(models, source, to, inputs)
    if notes:
        header = header[:2] + [f"NOTE: {n}" for n in notes] + header[2:]
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
    out += python_functions(models, sources)
    return "\n".join(out).rstrip() + "\n"


def python_functions(models, sources, delays_note: str = "") -> list[str]:
    """One keyword-only function per model (``numpy`` imported by the caller)."""
    from sympy.printing.numpy import NumPyPrinter
    out = []
    for m in models:
        printer = NumPyPrinter({"fully_qualified_modules": True})
        body = printer.doprint(m.expr)
        args = ", ".join(m.signals)
        sig = f"def {m.target}(*, {args}):" if args else f"def {m.target}(**_ignored):"
        doc = f"{m.target} in {m.unit}; inputs: " + (", ".join(f"{s} [{input_unit(s, sources)}]" for s in m.signals) or "none")
        if m.delays_s:
            doc += "; delays: " + ", ".join(f"{s} at t - {d:g} s" for s, d in sorted(m.delays_s.items()))
            doc += f" ({delays_note})" if delays_note else ""
        out += ["", f"{sig}", f'    """{doc}."""']
        out += [f"    return {body}", ""]
    return out


def _c(models, header) -> str:
    out = ["/*"] + [(" * " + h).rstrip() for h in header] + [
        " *", " * C99; compile with -lm. Arguments in alphabetical order of the signal names.", " */",
        "#include <math.h>", ""]
    return "\n".join(out + c_functions(models))


def c_functions(models) -> list[str]:
    """One C99 function per model, the signals as arguments in alphabetical order."""
    out = []
    for m in models:
        args = ", ".join(f"double {s}" for s in m.signals) or "void"
        out += [f"/* {m.target} in {m.unit} */", f"double {m.target}({args})", "{",
                f"    return {c_code(m.expr)};", "}", ""]
    return out


def _matlab(models, header, name) -> str:
    out = [f"function m = {name}()"] + [("% " + h).rstrip() for h in header] + [
        "%", f"% Usage: m = {name}(); a = m.{models[0].target}({', '.join(models[0].signals)});",
        "% (element-wise: vectors of samples work; arguments in alphabetical order)"]
    out += [f"  m.{mm.target} = @{mm.target};" for mm in models] + ["end", ""]
    for mm in models:
        args = ", ".join(mm.signals)
        out += [f"function out = {mm.target}({args})", f"  % {mm.target} in {mm.unit}",
                f"  out = {octave_code(mm.expr)};", "end", ""]
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
