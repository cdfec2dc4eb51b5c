"""Do a result's vehicle constants hold on another flight? (``droneid predict``)

A model is a property of the vehicle only if it holds from flight to flight. ``predict`` applies
it to flights it was not identified on; this module asks of each such flight what identify asks
of its training flights (:mod:`droneid.fitting.constancy`): the scales of the prior's thrust,
thrust-direction and drag terms (the vehicle constants, :data:`~droneid.fitting.constancy.VEHICLE_CONSTANT_ROLES`)
are fitted on the flight alone, every other part of the final model kept as identified, each with
its 95 % block-bootstrap interval over the flight's own time blocks, and tested against the
identified value and interval by the same Cochran's Q (p below :data:`~droneid.fitting.constancy.ALPHA`,
Holm over the target's constants, and a spread τ of at least
:data:`~droneid.fitting.constancy.MIN_TAU_REL` of the value). The identified interval's standard
error is its half-width / 1.96; where identify had several training flights that interval already
counts how they differ, so a flight of the same vehicle in the same condition should agree.

A constant that does not hold says: this flight's vehicle, payload or battery differs from the
training flights', or the model lacks something that moves the constant on this flight (the
identify verdict's "NOT vehicle constants" says the same of the training flights). The check
never changes a prediction; it is reported beside it.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from droneid.core.expressions import parse_expression
from droneid.core.regression import bootstrap_draws, robust_fit
from droneid.dataset.validation import time_blocks
from droneid.errors import DroneIdError
from droneid.fitting.constancy import ALPHA, MIN_TAU_REL, MIN_UNIT_ROWS, VEHICLE_CONSTANT_ROLES, heterogeneity, holm_flags
from droneid.fitting.terms import evaluate_expr

__all__ = ["ConstantCheck", "identified_constants", "check_constants", "constants_line"]

_Z95 = 1.959964


@dataclass(frozen=True)
class ConstantCheck:
    """One vehicle constant on one flight (predict's ``targets.<t>.constants``).

    flight : the flight's name; label : the term, ``⟨name⟩``; value, low, high : its scale fitted
    on this flight alone (1 = nominal) and the 95 % block-bootstrap interval; identified :
    (value, low, high) in the result; p : Cochran's Q p-value of the two; holds : False when the
    test flags it (Holm over the target's constants on this flight), True otherwise."""
    flight: str
    label: str
    value: float
    low: float
    high: float
    identified: tuple[float, float, float]
    p: float
    holds: bool

    def to_dict(self) -> dict:
        return {"flight": self.flight, "label": self.label, "value": self.value, "low": self.low,
                "high": self.high, "identified": list(self.identified), "p": self.p, "holds": self.holds}

    @classmethod
    def from_dict(cls, d: Mapping) -> "ConstantCheck":
        return cls(str(d["flight"]), str(d["label"]), float(d["value"]), float(d["low"]), float(d["high"]),
                   tuple(float(v) for v in d["identified"]), float(d["p"]), bool(d["holds"]))

    def text(self) -> str:
        v, lo, hi = self.identified
        return (f"{self.label} {self.value:.4g} [{self.low:.4g}, {self.high:.4g}] against {v:.4g} "
                f"[{lo:.4g}, {hi:.4g}] identified" + ("" if self.holds else f" (p = {self.p:.2g}): DOES NOT HOLD"))


def identified_constants(tr: Mapping) -> dict:
    """{label: {"value", "low", "high", "expr"}}: the vehicle constants of one target of a
    result.json (``targets.<t>``): the final rung's prior terms whose role is a vehicle
    constant's, with their 95 % interval, leaving out those held at nominal or pulled to a bound
    (no estimate). Empty for a result written before roles were recorded."""
    ladder = tr.get("ladder") or []
    if not ladder or not isinstance(ladder[-1], Mapping):
        return {}
    final = ladder[-1]
    terms, ivs = final.get("terms") or {}, final.get("intervals") or {}
    skip = set(final.get("held") or {}) | set(final.get("at_bound") or {})
    out = {}
    for f in tr.get("empirical_terms") or []:
        lab = f"⟨{f.get('name')}⟩"
        if f.get("role") not in VEHICLE_CONSTANT_ROLES or lab not in terms or lab not in ivs or lab in skip:
            continue
        try:
            v, (lo, hi) = float(terms[lab]), (float(x) for x in ivs[lab])
        except (TypeError, ValueError):
            continue
        if all(math.isfinite(x) for x in (v, lo, hi)) and hi > lo:
            out[lab] = {"value": v, "low": lo, "high": hi, "expr": str(f.get("expr"))}
    return out


def check_constants(constants: Mapping[str, Mapping], columns: Mapping[str, np.ndarray], y: np.ndarray,
                    predicted: np.ndarray, t: np.ndarray, flight: np.ndarray, names: Sequence[str],
                    *, seed: int = 0) -> tuple[ConstantCheck, ...]:
    """Each vehicle constant of :func:`identified_constants` fitted on every flight alone (rows of
    ``flight`` == i, named ``names[i]``; ``columns``, ``y`` (m/s²), ``predicted`` (the final
    model's v̇ on the rows) and ``t`` (s) as predict built them), tested against its identified
    value (see the module docstring). A flight with fewer than
    :data:`~droneid.fitting.constancy.MIN_UNIT_ROWS` usable rows is not checked."""
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
    lo, hi = np.zeros(len(labs)), np.full(len(labs), np.inf)
    out = []
    for i, name in enumerate(names):
        rows = np.flatnonzero(ok & (np.asarray(flight) == i))
        if rows.size < MIN_UNIT_ROWS:
            continue
        Ai, zi = A[rows], z[rows]
        fit = robust_fit(Ai, zi, lo, hi)
        blocks = time_blocks(np.asarray(t, float)[rows], np.zeros(rows.size, int))
        b = np.unique(blocks).size
        draws = bootstrap_draws(Ai, zi, blocks, fit, lo, hi, seed=seed)
        se = np.std(draws, axis=0, ddof=1) * math.sqrt(b / max(b - 1, 1))
        pct = np.percentile(draws, [2.5, 97.5], axis=0)
        het = {}
        for j, lab in enumerate(labs):
            c = constants[lab]
            het[lab] = heterogeneity([c["value"], fit.beta[j]], [(c["high"] - c["low"]) / (2 * _Z95), se[j]])
        flags = holm_flags({lab: h["p"] for lab, h in het.items()}, ALPHA)
        for j, lab in enumerate(labs):
            c, h = constants[lab], het[lab]
            moved = flags[lab] and h["tau"] >= MIN_TAU_REL * abs(h["mean"])
            out.append(ConstantCheck(str(name), lab, float(fit.beta[j]), float(pct[0, j]), float(pct[1, j]),
                                     (c["value"], c["low"], c["high"]), float(h["p"]), not moved))
    return tuple(out)


def constants_line(checks: Sequence[ConstantCheck]) -> str:
    """One line for predict's report: the verdict first (every constant holds, or which do not and
    what that means), then each flight's values; "" without checks."""
    if not checks:
        return ""
    bad = [c for c in checks if not c.holds]
    rule = ("each fitted on its flight alone against the result's interval; Cochran's Q, Holm at α = 0.01, "
            "a spread of 1 % or more")
    if not bad:
        one = len({c.flight for c in checks}) == 1
        head = f"vehicle constants on {'this flight' if one else 'these flights'}: every one holds ({rule})"
    else:
        flights = list(dict.fromkeys(c.flight for c in bad))
        labels = list(dict.fromkeys(c.label for c in bad))
        head = (f"VEHICLE CONSTANTS DO NOT HOLD on {', '.join(flights)}: {', '.join(labels)} "
                f"{'differs' if len(labels) == 1 else 'differ'} from the result's by more than the noise allows "
                f"({rule}). The vehicle, payload or battery of "
                f"{'this flight' if len(flights) == 1 else 'these flights'} differ from the training flights', "
                f"or something the model lacks moves them here (a tilt or horizontal thrust scale also falls the "
                f"less a flight tilts: noise in the attitude pulls it toward 0)")
    per: dict[str, list[str]] = {}
    for c in checks:
        per.setdefault(c.flight, []).append(c.text())
    return head + ". " + "; ".join(f"{f}: " + ", ".join(v) for f, v in per.items())
