"""The physics guard on found terms: what a term of a vehicle model may depend on, whoever found it.

One home for the rule, used by identify's ladder (:func:`droneid.identify.ladder.final_rung`, on every
evolved SNGP term) and by the diagnosis's open-ended search (:mod:`droneid.diagnosis.residual_search`, on
its equation). A term is refused, with the reason, when it

- uses **one motor** (or a few) of a per-motor family but not the others (``rpm2`` alone, or
  ``motor1·motor3``): a vehicle constant cannot depend on one motor unless the diagnosis found
  the per-motor effect (``per_motor``);
- depends on **absolute position** (``x``, ``y``, ``lat``, ``lon``, ``alt``, ``baro_alt``):
  the vehicle's dynamics do not know where it is; height ``z`` only where ground effect is
  possible (``height``: the flights spend time near the ground, so the diagnosis could test it);
- is **unit-inconsistent**: a sum of quantities of different units (``vx + pitch``), or a
  function other than a power or ``abs`` of a quantity with a unit (``sin(vx)``, ``exp(rpm1)``).
  Numbers that multiply a signal are taken as pure numbers (an evolved constant carries no
  unit); a number added on its own is an offset in the sum's unit (``vx − 0.5`` is fine).
  Angles (rad) are numbers. Signals whose unit droneid does not know are not checked.

Pure functions, no pipeline imports beyond the canonical signal table.
"""
from __future__ import annotations

import re
from collections.abc import Iterable, Mapping

import sympy as sp

from droneid.errors import MissingSignalError
from droneid.logs.flight import canonical_unit

__all__ = ["POSITION_SIGNALS", "dimension", "term_problem", "guard_terms"]

#: signals that say where the vehicle is, not how it moves (height ``z`` is handled apart)
POSITION_SIGNALS = frozenset({"x", "y", "lat", "lon", "alt", "baro_alt"})

_PER_MOTOR = re.compile(r"^(rpm|motor)([1-9][0-9]?)$")
# base dimensions: length, time, mass, voltage, current
_BASE = ("L", "T", "M", "V", "A")
_UNITS = {"m": {"L": 1}, "s": {"T": 1}, "rad": {}, "deg": {}, "1": {}, "N": {"M": 1, "L": 1, "T": -2},
          "V": {"V": 1}, "A": {"A": 1}, "rpm": {"T": -1}, "erpm": {"T": -1}, "min": {"T": 1}}
#: the dimension of a prior feature's symbol: an acceleration (its coefficient is a scale)
ACCELERATION = (1, -2, 0, 0, 0)
_NONE = (0, 0, 0, 0, 0)


def _parse_unit(unit: str) -> tuple | None:
    """``"m/s^2"`` -> (1, -2, 0, 0, 0); None for a unit this table does not know."""
    out = dict.fromkeys(_BASE, 0)
    for k, part in enumerate(str(unit).replace(" ", "").split("/")):
        base, _, power = part.partition("^")
        if base not in _UNITS:
            return None
        for d, e in _UNITS[base].items():
            out[d] += (-1 if k else 1) * e * int(power or 1)
    return tuple(out[d] for d in _BASE)


def _signal_dimension(name: str, units: Mapping[str, str] | None) -> tuple | None:
    if units is not None and name in units:
        return _parse_unit(units[name])
    try:
        return _parse_unit(canonical_unit(name))
    except MissingSignalError:
        return None


class _Inconsistent(Exception):
    pass


def dimension(expr: sp.Expr, units: Mapping[str, str] | None = None,
              symbols: Mapping[str, tuple] | None = None) -> tuple | None:
    """The dimension of ``expr`` as exponents of (length, time, mass, voltage, current), None when
    a signal's unit is unknown. ``units``: {signal: unit} overriding the canonical units (e.g.
    ``erpm``); ``symbols``: {name: dimension} of further symbols (prior features: acceleration).
    Raises ValueError naming the first inconsistency (see the module docstring)."""
    def dim(e):
        if e.is_Number or e in (sp.pi, sp.E):
            return _NONE
        if e.is_Symbol:
            if symbols and e.name in symbols:
                return tuple(symbols[e.name])
            return _signal_dimension(e.name, units)
        if isinstance(e, sp.Mul):
            out = list(_NONE)
            for a in e.args:
                d = dim(a)
                if d is None:
                    return None
                out = [x + y for x, y in zip(out, d)]
            return tuple(out)
        if isinstance(e, sp.Add):
            dims = [dim(a) for a in e.args if not a.is_number]   # a constant alone (2.25, pi) is an offset
            known = [d for d in dims if d is not None]
            if any(d != known[0] for d in known):
                raise _Inconsistent(f"it adds quantities of different units ({sp.sstr(e)})")
            return known[0] if len(known) == len(dims) and known else None
        if isinstance(e, sp.Pow):
            b, p = dim(e.base), dim(e.exp)
            if p not in (None, _NONE):
                raise _Inconsistent(f"its exponent has a unit ({sp.sstr(e)})")
            if b is None or b == _NONE:
                return b
            if not e.exp.is_Number:
                raise _Inconsistent(f"it raises a quantity with a unit to a variable power ({sp.sstr(e)})")
            return tuple(float(x * e.exp) for x in b)
        if isinstance(e, (sp.Abs, sp.Min, sp.Max)):
            dims = [dim(a) for a in e.args]
            known = [d for d in dims if d is not None]
            if any(d != known[0] for d in known):
                raise _Inconsistent(f"it compares quantities of different units ({sp.sstr(e)})")
            return known[0] if len(known) == len(dims) else None
        if isinstance(e, (sp.Function, sp.sign)):
            for a in e.args:
                d = dim(a)
                if d not in (None, _NONE):
                    raise _Inconsistent(f"it takes {type(e).__name__} of a quantity with a unit ({sp.sstr(e)})")
            return _NONE
        return None
    try:
        d = dim(sp.sympify(expr))
    except _Inconsistent as exc:
        raise ValueError(str(exc)) from None
    return None if d is None else tuple(0 if x == 0 else x for x in d)


def term_problem(expr: sp.Expr, available: Iterable[str], *, per_motor: bool = False, height: bool = False,
                 units: Mapping[str, str] | None = None, symbols: Mapping[str, tuple] | None = None) -> str | None:
    """Why the term ``expr`` (sympy over signals, and ``symbols``: prior features) cannot be part
    of a vehicle model, or None when it can (module docstring). ``available``: the signals the
    data offer (a per-motor family's members); ``per_motor``: the diagnosis found the per-motor
    thrust effect; ``height``: ground effect is possible on these flights."""
    names = {s.name for s in sp.sympify(expr).free_symbols}
    have = set(available)
    if not per_motor:
        for fam in ("rpm", "motor"):
            used = {n for n in names if (m := _PER_MOTOR.match(n)) and m.group(1) == fam}
            every = {n for n in have if (m := _PER_MOTOR.match(n)) and m.group(1) == fam}
            every |= used
            if used and used != every:
                return (f"it uses {', '.join(sorted(used, key=_motor_order))} but not "
                        f"{', '.join(sorted(every - used, key=_motor_order))}: a vehicle constant cannot depend "
                        "on one motor unless the per-motor effect was found")
    where = sorted(names & POSITION_SIGNALS)
    if where:
        return f"it depends on the absolute position ({', '.join(where)}): the dynamics do not know where the vehicle is"
    if "z" in names and not height:
        return ("it depends on the height z, and these flights leave no room for ground effect "
                "(no time near the ground)")
    try:
        dimension(expr, units, symbols)
    except ValueError as exc:
        return f"it is unit-inconsistent: {exc}"
    return None


def _motor_order(name: str) -> tuple:
    m = _PER_MOTOR.match(name)
    return (m.group(1), int(m.group(2))) if m else (name, 0)


def guard_terms(terms, labels, available, **kw) -> tuple[list[int], list[str]]:
    """(indices of the ``terms`` that pass :func:`term_problem`, one line per refused term,
    "dropped LABEL: REASON") with the keywords of :func:`term_problem`."""
    keep, notes = [], []
    for i, (t, lab) in enumerate(zip(terms, labels)):
        why = term_problem(t, available, **kw)
        if why is None:
            keep.append(i)
        else:
            notes.append(f"dropped {lab}: {why}")
    return keep, notes
