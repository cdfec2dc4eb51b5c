"""Do a result's vehicle constants hold on another flight? (``droneid predict``)

A model is a property of the vehicle only if it holds from flight to flight. ``predict`` applies
it to flights it was not identified on; this module asks of each such flight what identify asks
of its training flights (:mod:`droneid.fitting.constancy`). The scales of the prior's thrust,
thrust-direction and drag terms (the vehicle constants,
:data:`~droneid.fitting.constancy.VEHICLE_CONSTANT_ROLES`) are fitted on the flight alone, every
other part of the final model kept as identified, each with its block-bootstrap standard error
over the flight's own time blocks, and compared with what the result says a flight of this
vehicle gives (:func:`identified_constants`):

- with several training flights, the random-effects mean μ of their per-flight values and the
  spread of a NEW flight about it, √(se_μ² + τ²) (τ: the flights' spread, DerSimonian-Laird;
  se_μ from the Hartung-Knapp interval of μ), with k − 1 degrees of freedom;
- with one training flight, its value and the standard error of its interval (half-width /
  1.96): one flight cannot show how flights differ, and the line says so.

A constant DOES NOT HOLD when ``t = (θ − μ) / √(se_new² + se_μ² + τ²)`` has p below
:data:`~droneid.fitting.constancy.ALPHA` (two-sided, Holm over the target's constants on the
flight) and the difference is at least :data:`~droneid.fitting.constancy.MIN_TAU_REL` of μ: the
constancy test's rule (:func:`~droneid.fitting.constancy.moved`). Each flight is fitted without
the physics bounds, as the training flights' units are (:func:`~droneid.fitting.constancy.unit_bounds`:
a flight that pushes a drag through 0 is tested, not set aside). A constant the flight does not
excite (its rows do not move it: an interval of zero width; or its interval wider than ±:data:`~droneid.fitting.terms.IDENTIFIABLE_REL` of what a new
flight should give, max(|μ|, 1): a width rule that does not depend on the flight's own value, so
a low reading is not dropped sooner than a high one) is "not identifiable on this flight", and a
flight that was trained on is not checked (its data are in the result's value).

A constant that does not hold says: this flight's vehicle, payload or battery differs from the
training flights', or the model lacks something that moves the constant on this flight. The
check never changes a prediction; it is reported beside it.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special

from droneid.core.expressions import evaluate_expr, parse_expression
from droneid.dataset.validation import time_blocks
from droneid.errors import DroneIdError
from droneid.fitting.constancy import (ALPHA, MIN_UNIT_ROWS, VEHICLE_CONSTANT_ROLES, holm_flags, moved,
                                       new_flight_expectation, new_flight_p, rule_text, unit_bounds,
                                       unit_estimate)
from droneid.fitting.terms import IDENTIFIABLE_REL

__all__ = ["ConstantCheck", "identified_constants", "check_constants", "constants_line"]


def _number(v) -> float:
    return math.nan if v is None else float(v)


@dataclass(frozen=True)
class ConstantCheck:
    """One vehicle constant on one flight (predict's ``targets.<t>.constants``).

    flight : the flight's name; label : the term, ``⟨name⟩``; role : its role (thrust, tilt,
    drag); value, low, high : its scale fitted on this flight alone (1 = nominal) and the 95 %
    block-bootstrap interval; expected : (μ, low, high) what a flight of this vehicle gives by
    the result (μ ± 1.96 of the spread of a new flight about it); p : the test's p-value;
    holds : True, False (DOES NOT HOLD) or None (not checked: ``why``); trained_on : the result's
    training flights behind ``expected`` (1: how flights differ is not in it)."""
    flight: str
    label: str
    role: str
    value: float
    low: float
    high: float
    expected: tuple[float, float, float]
    p: float
    holds: bool | None
    why: str = ""
    trained_on: int = 0

    def to_dict(self) -> dict:
        return {"flight": self.flight, "label": self.label, "role": self.role, "value": self.value,
                "low": self.low, "high": self.high, "expected": list(self.expected), "p": self.p,
                "holds": self.holds, "why": self.why, "trained_on": self.trained_on}

    @classmethod
    def from_dict(cls, d: Mapping) -> "ConstantCheck":
        return cls(str(d["flight"]), str(d["label"]), str(d.get("role") or ""), _number(d["value"]),
                   _number(d["low"]), _number(d["high"]), tuple(_number(v) for v in d["expected"]),
                   _number(d["p"]), d["holds"] if d["holds"] is None else bool(d["holds"]), str(d.get("why") or ""),
                   int(d.get("trained_on") or 0))

    def text(self) -> str:
        mu, lo, hi = self.expected
        if self.holds is None:
            return f"{self.label} not checked ({self.why})"
        return (f"{self.label} {self.value:.4g} [{self.low:.4g}, {self.high:.4g}], a flight of the result's vehicle "
                f"{mu:.4g} [{lo:.4g}, {hi:.4g}], p = {self.p:.2g}" + ("" if self.holds else ": DOES NOT HOLD"))


def identified_constants(tr: Mapping) -> dict:
    """{label: {"value", "se", "df", "role", "expr", "flights"}}: the vehicle constants of one
    target of a result.json (``targets.<t>``), those of the final rung's prior terms whose role
    is a vehicle constant's and that the result neither held at nominal nor pulled to a bound,
    with what a NEW flight of the vehicle should give: ``value`` ± ``se`` with ``df`` degrees of
    freedom (inf: normal) and ``flights`` the training flights behind it (see the module
    docstring). Empty for a result written before roles were recorded."""
    ladder = tr.get("ladder") or []
    if not ladder or not isinstance(ladder[-1], Mapping):
        return {}
    final = ladder[-1]
    terms, ivs = final.get("terms") or {}, final.get("intervals") or {}
    skip = set(final.get("held") or {}) | set(final.get("at_bound") or {})
    constancy = tr.get("constancy") or {}
    out = {}
    for f in tr.get("empirical_terms") or []:
        name = str(f.get("name"))
        lab = f"⟨{name}⟩"
        if f.get("role") not in VEHICLE_CONSTANT_ROLES or lab not in terms or lab not in ivs or lab in skip:
            continue
        try:
            v, (lo, hi) = float(terms[lab]), (float(x) for x in ivs[lab])
        except (TypeError, ValueError):
            continue
        if not (all(math.isfinite(x) for x in (v, lo, hi)) and hi > lo):
            continue
        entry = {**new_flight_expectation(v, lo, hi, constancy.get(name)), "role": str(f["role"]),
                 "expr": str(f.get("expr"))}
        out[lab] = entry
    return out


def check_constants(constants: Mapping[str, Mapping], columns: Mapping[str, np.ndarray], y: np.ndarray,
                    predicted: np.ndarray, t: np.ndarray, flight: np.ndarray, names: Sequence[str],
                    trained: Sequence[str] = (), *, seed: int = 0) -> tuple[ConstantCheck, ...]:
    """Each vehicle constant of :func:`identified_constants` fitted on every flight alone (rows of
    ``flight`` == i, named ``names[i]``; ``columns``, ``y`` (m/s²), ``predicted`` (the final
    model's v̇ on the rows) and ``t`` (s) as predict built them) and tested (module docstring).
    A flight named in ``trained`` (a training flight of the result) or with fewer than
    :data:`~droneid.fitting.constancy.MIN_UNIT_ROWS` usable rows gets "not checked"."""
    if not constants:
        return ()
    n = len(y)
    labs = list(constants)
    try:
        exprs = [parse_expression(constants[lab]["expr"], list(columns), what=f"the term {lab}") for lab in labs]
        A = np.column_stack([evaluate_expr(e, columns, n) for e in exprs])
    except (DroneIdError, KeyError):
        return ()     # a term over a signal these flights lack: nothing to check
    coef = np.array([constants[lab]["value"] for lab in labs])
    rest = np.asarray(predicted, float) - A @ coef          # every other part of the final model, as identified
    z = np.asarray(y, float) - rest
    ok = np.isfinite(z) & np.all(np.isfinite(A), axis=1)
    lo, hi = unit_bounds(np.zeros(len(labs)), np.full(len(labs), np.inf))      # each flight unbounded, as the training ones
    nan3 = (math.nan, math.nan, math.nan)
    out = []
    for i, name in enumerate(names):
        rows = np.flatnonzero(ok & (np.asarray(flight) == i))

        def unchecked(why):
            return [ConstantCheck(str(name), lab, constants[lab]["role"], math.nan, math.nan, math.nan, nan3,
                                  math.nan, None, why, constants[lab]["flights"]) for lab in labs]
        if str(name) in set(trained):
            out += unchecked("a training flight of the result: its data are in the value it is tested against")
            continue
        if rows.size < MIN_UNIT_ROWS:
            out += unchecked(f"{rows.size} rows, fewer than {MIN_UNIT_ROWS}")
            continue
        Ai, zi = A[rows], z[rows]
        fit, se, pct, dof = unit_estimate(Ai, zi, time_blocks(np.asarray(t, float)[rows], np.zeros(rows.size, int)), lo, hi,
                                     seed=seed)
        res, ps = {}, {}
        for j, lab in enumerate(labs):
            c = constants[lab]
            v, half = float(fit.beta[j]), (float(pct[1, j]) - float(pct[0, j])) / 2
            q = float(special.stdtrit(c["df"], 0.975)) if math.isfinite(c["df"]) else 1.959964
            expected = (c["value"], max(c["value"] - q * c["se"], 0.0), c["value"] + q * c["se"])  # scales >= 0
            if not 0 < half <= IDENTIFIABLE_REL * max(abs(c["value"]), 1.0):     # 0: its rows do not move it
                res[lab] = ConstantCheck(str(name), lab, c["role"], v, float(pct[0, j]), float(pct[1, j]), expected,
                                         math.nan, None, "not identifiable on this flight: its rows do not move the "
                                         f"term, or its interval is wider than ±{100 * IDENTIFIABLE_REL:.0f} % of what a "
                                         "new flight should give", c["flights"])
                continue
            ps[lab] = new_flight_p(v, float(se[j]), c, dof)
            res[lab] = (v, float(pct[0, j]), float(pct[1, j]), expected)
        flags = holm_flags(ps, ALPHA)
        for lab in labs:
            r = res[lab]
            if isinstance(r, ConstantCheck):
                out.append(r)
                continue
            v, l95, h95, expected = r
            bad = moved(flags[lab], abs(v - expected[0]), expected[0])
            out.append(ConstantCheck(str(name), lab, constants[lab]["role"], v, l95, h95, expected, ps[lab], not bad,
                                     trained_on=constants[lab]["flights"]))
    return tuple(out)


def constants_line(checks: Sequence[ConstantCheck]) -> str:
    """One line for predict's report: the verdict first (every constant holds, or which do not and
    what that means), then each flight's values; "" without checks."""
    if not checks:
        return ""
    tested = [c for c in checks if c.holds is not None]
    bad = [c for c in tested if not c.holds]
    rule = rule_text("each fitted on its flight alone, against the spread of a new flight of the result's vehicle "
                     "and its own noise together (the band shown leaves its own noise out); two-sided p")
    one = len({c.flight for c in checks}) == 1
    if not tested:
        head = "vehicle constants not checked on " + ("this flight" if one else "these flights")
    elif not bad:
        head = f"vehicle constants on {'this flight' if one else 'these flights'}: every one tested holds ({rule})"
    else:
        flights = list(dict.fromkeys(c.flight for c in bad))
        labels = list(dict.fromkeys(c.label for c in bad))
        head = (f"VEHICLE CONSTANTS DO NOT HOLD on {', '.join(flights)}: {', '.join(labels)} "
                f"{'differs' if len(labels) == 1 else 'differ'} from what a flight of the result's vehicle gives "
                f"by more than the noise allows ({rule}). The vehicle, payload or battery of "
                f"{'this flight differs' if len(flights) == 1 else 'these flights differ'} from the training "
                f"flights', or something the model lacks moves {'it' if len(labels) == 1 else 'them'} here")
        if any(c.role == "tilt" or (c.role == "thrust" and not c.label.endswith("_z⟩")) for c in bad):
            head += (" (a thrust-direction or horizontal thrust scale also falls the less a flight tilts: noise in "
                     "the logged attitude pulls it toward 0)")
    if any(c.trained_on == 1 for c in tested):
        head += ("; the result has one training flight, so how flights of the vehicle differ is not in its "
                 "interval")
    per: dict[str, list[str]] = {}
    for c in checks:
        per.setdefault(c.flight, []).append(c.text())
    return head + ". " + "; ".join(f"{f}: " + ", ".join(v) for f, v in per.items())
