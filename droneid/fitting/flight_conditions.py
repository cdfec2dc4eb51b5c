"""Flight conditions behind vehicle constants that move: is a constant's spread between the
training flights taken away by a condition of each flight's own (wind, a clock offset, a
payload), or does it stay a property the model lacks? (docs/estimates.md, "leads")

The tests read :class:`~droneid.fitting.constancy.Constancy` records and use the constancy rule
of :mod:`droneid.fitting.constancy` (:func:`~droneid.fitting.constancy.heterogeneity`, Holm, the
spread rule): :func:`explained` for a refit with a condition free, :func:`one_factor_per_flight`
for a payload or a battery across the targets.
"""
from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from droneid.fitting.constancy import Constancy, heterogeneity, holm_flags, moved, se_of_interval, spread_text

__all__ = ["explained", "one_factor_per_flight"]


# a payload per flight: one factor on every axis's thrust

def one_factor_per_flight(moved_terms: Mapping[str, Constancy], others: Mapping[str, Constancy]) -> dict[str, str]:
    """{label: one lead sentence} testing a payload or a battery per flight as the cause of thrust
    scales that move between flights (``moved_terms``: {label: :class:`Constancy`} of the thrust
    terms called NOT constant). Such a condition scales the thrust per unit mass of every axis by
    one factor per flight, so a moved term's per-flight ratio to another axis's thrust term
    (``others``: {label: Constancy}; the reference is the most precise of them, by the median
    width of its per-flight intervals) is then one value: Cochran's Q of the ratios, each
    flight's standard error from the two 95 % intervals (:func:`se_of_interval`, the axes'
    noise independent, the delta method), read as χ²(k − 1) as :class:`SharedConstant` reads its
    intervals, Holm over the moved terms and the spread rule (:func:`moved`). A ratio that holds
    says such a per-flight condition explains the move ("constant") when the term's own spread
    would still show with the ratios' relative noise (:func:`explained`'s power check), else
    "not told apart"; one that still moves says the reference axis does not move with it. Terms
    with fewer than two flights in common with the reference are left out."""
    tests = {}
    for lab, c in moved_terms.items():
        cands = {o: r for o, r in others.items() if o != lab and r.unit == "flight"}
        if c.unit != "flight" or not cands:
            continue
        ref = min(cands, key=lambda o: float(np.median([hi - lo for _, lo, hi in cands[o].per_unit.values()])))
        common = [f for f in c.per_unit if f in cands[ref].per_unit]
        values, ratios, rel = [], [], []
        for f in common:
            (a, a_lo, a_hi), (b, b_lo, b_hi) = c.per_unit[f], cands[ref].per_unit[f]
            if a == 0 or b == 0:
                continue
            values.append(a)
            ratios.append(a / b)
            rel.append(math.hypot(se_of_interval(a_lo, a_hi) / a, se_of_interval(b_lo, b_hi) / b))
        h = heterogeneity(ratios, np.abs(ratios) * np.asarray(rel))
        if math.isfinite(h["p"]):
            # the power check of explained(): the spread the term had, read with the ratios' noise
            power = heterogeneity(values, np.abs(values) * np.asarray(rel))
            tests[lab] = (ref, ratios, h, power)
    flags = holm_flags({lab: t[2]["p"] for lab, t in tests.items()})
    shows = holm_flags({lab: t[3]["p"] for lab, t in tests.items()})
    out = {}
    for lab, (ref, ratios, h, power) in tests.items():
        if moved(flags[lab], h["tau"], h["mean"]):
            word = f"still NOT constant ({ref} does not move with it)"
        elif moved(shows[lab], power["tau"], power["mean"]):
            word = "constant (the axes' thrust moves together from flight to flight)"
        else:
            word = f"not told apart ({ref} too uncertain per flight to show the spread {lab} had)"
        out[lab] = (f"with a payload or a battery of its own on each training flight (one factor on every axis's "
                    f"thrust per unit mass: {lab} / {ref} per flight {min(ratios):.4g}-{max(ratios):.4g}, "
                    f"p = {h['p']:.2g}, spread τ {spread_text(100 * h['tau'] / abs(h['mean']))}): {word}")
    return out


# does a condition of each flight explain constants that moved?

def explained(before: Mapping[str, Constancy], after: Mapping[str, Constancy]) -> dict[str, tuple[str, float]]:
    """{label: (verdict, se growth)} of vehicle constants that moved (``before``: their
    :class:`Constancy` records) refit with one condition of each flight's own (``after``). A
    constant the condition holds must hold *because* the condition took its spread away, not
    because a condition collinear with it made every flight's estimate too uncertain to
    disagree: so the spread it had (``before``'s per-unit values) is tested again with the
    refit's standard errors and degrees of freedom (``after``'s noise), by the same
    :func:`heterogeneity`, Holm over the labels and the spread rule. Verdicts: "still NOT
    constant" (the refit still moves), "constant" (the refit holds and the old spread would
    still show with its noise), "not told apart" (the refit holds, the old spread would not
    show: the condition and the constant are confounded on these flights). ``se growth`` is the
    median ratio of the refit's per-unit standard error to the original's (NaN where unknown)."""
    power, growth = {}, {}
    for lab, c in after.items():
        b = before.get(lab)
        if b is None or c.constant is None:
            continue
        units = [u for u in c.noise if u in b.per_unit]
        power[lab] = heterogeneity([b.per_unit[u][0] for u in units], [c.noise[u][0] for u in units],
                                   [c.noise[u][1] for u in units])
        ratio = [c.noise[u][0] / b.noise[u][0] for u in units if b.noise.get(u, (0.0,))[0] > 0]
        growth[lab] = float(np.median(ratio)) if ratio else math.nan
    flags = holm_flags({lab: h["p"] for lab, h in power.items()})
    out = {}
    for lab, h in power.items():
        if after[lab].constant is False:
            out[lab] = ("still NOT constant", growth[lab])
        elif moved(flags[lab], h["tau"], h["mean"]):
            out[lab] = ("constant", growth[lab])
        else:
            out[lab] = ("not told apart", growth[lab])
    return out
