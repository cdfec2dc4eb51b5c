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

def _noise(c: Constancy, unit: str) -> tuple[float, float]:
    """(se, df) of ``c``'s estimate on ``unit`` as its constancy test read it (``c.noise``), else
    the standard error its 95 % interval stands for, known (a record read back from JSON)."""
    if unit in c.noise:
        return c.noise[unit]
    _, lo, hi = c.per_unit[unit]
    return se_of_interval(lo, hi), math.inf


def _ratio_test(a: Constancy, b: Constancy) -> tuple[list, dict, dict] | None:
    """(ratios, test, power) of ``a``'s per-flight values over ``b``'s: Cochran's Q of the ratios
    (relative variance the sum of the two, Welch-Satterthwaite degrees of freedom, the axes'
    noise independent: the delta method) and the power check, ``a``'s own values read with the
    ratios' relative noise; None with fewer than two flights in common."""
    ratios, values, rel, dfs = [], [], [], []
    for f in a.per_unit:
        if f not in b.per_unit or a.per_unit[f][0] == 0 or b.per_unit[f][0] == 0:
            continue
        (va, (sa, da)), (vb, (sb, db)) = (a.per_unit[f][0], _noise(a, f)), (b.per_unit[f][0], _noise(b, f))
        ra, rb = (sa / va) ** 2, (sb / vb) ** 2
        ratios.append(va / vb)
        values.append(va)
        rel.append(math.sqrt(ra + rb))
        spread = ra ** 2 / da + rb ** 2 / db            # Welch-Satterthwaite; 0 when both are known
        dfs.append((ra + rb) ** 2 / spread if spread > 0 else math.inf)
    if len(ratios) < 2:
        return None
    rel = np.asarray(rel)
    test = heterogeneity(ratios, np.abs(ratios) * rel, dfs)
    return (ratios, test, heterogeneity(values, np.abs(values) * rel, dfs)) if math.isfinite(test["p"]) else None


def one_factor_per_flight(moved_terms: Mapping[str, Constancy], others: Mapping[str, Constancy]) -> dict[str, str]:
    """{label: one lead sentence} testing a payload or a battery per flight as the cause of thrust
    scales that move between flights (``moved_terms``: {label: :class:`Constancy`} of the thrust
    terms called NOT constant). Such a condition scales the thrust per unit mass of every axis by
    one factor per flight, so a moved term's per-flight ratio to another axis's thrust term
    (``others``: {label: Constancy} over flights; the reference is the most precise of them, by
    the median width of its per-flight intervals) is then one value. The test is the constancy
    test's (:func:`_ratio_test`: each flight's standard error and degrees of freedom as the
    constancy test read them, ``Constancy.noise``), Holm over the pairs tested (a pair that is
    each other's reference is one test) and the spread rule (:func:`moved`). A ratio that holds
    says such a per-flight condition explains the move ("constant") when the term's own spread
    would still show with the ratios' relative noise (:func:`explained`'s power check), else
    "not told apart"; one that still moves says the reference axis does not move with it."""
    tests = {}
    for lab, c in moved_terms.items():
        cands = {o: r for o, r in others.items() if o != lab and r.unit == "flight"}
        if c.unit != "flight" or not cands:
            continue
        ref = min(cands, key=lambda o: float(np.median([hi - lo for _, lo, hi in cands[o].per_unit.values()])))
        pair = frozenset((lab, ref))
        if pair in tests:
            continue
        got = _ratio_test(c, cands[ref])
        if got is not None:
            tests[pair] = (lab, ref, *got)
    key = {pair: " / ".join(sorted(pair)) for pair in tests}
    flags = holm_flags({key[pr]: t[3]["p"] for pr, t in tests.items()})
    shows = holm_flags({key[pr]: t[4]["p"] for pr, t in tests.items()})
    out = {}
    for pair, (lab, ref, ratios, h, power) in tests.items():
        if moved(flags[key[pair]], h["tau"], h["mean"]):
            word = f"still NOT constant ({ref} does not move with it)"
        elif moved(shows[key[pair]], power["tau"], power["mean"]):
            word = "constant (the axes' thrust moves together from flight to flight)"
        else:
            word = f"not told apart ({ref} too uncertain per flight to show the spread {lab} had)"
        said = (f"with a payload or a battery of its own on each training flight (one factor on every axis's "
                f"thrust per unit mass: {lab} / {ref} per flight {min(ratios):.4g}-{max(ratios):.4g}, "
                f"p = {h['p']:.2g}, spread τ {spread_text(100 * h['tau'] / abs(h['mean']))}): {word}")
        out[lab] = said
        if ref in moved_terms:
            out.setdefault(ref, said)
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
    show: the condition and the constant are confounded on these flights), "untestable" (the
    refit could not be tested over the same flights). ``se growth`` is the median ratio of the
    refit's per-unit standard error to the original's (NaN where unknown)."""
    power, growth, out = {}, {}, {}
    for lab, c in after.items():
        b = before.get(lab)
        if b is None:
            continue
        units = [u for u in c.noise if u in b.per_unit]
        if c.constant is None or c.unit != b.unit or len(units) < 2:
            out[lab] = ("untestable", math.nan)
            continue
        power[lab] = heterogeneity([b.per_unit[u][0] for u in units], [c.noise[u][0] for u in units],
                                   [c.noise[u][1] for u in units])
        ratio = [c.noise[u][0] / b.noise[u][0] for u in units if b.noise.get(u, (0.0,))[0] > 0]
        growth[lab] = float(np.median(ratio)) if ratio else math.nan
    flags = holm_flags({lab: h["p"] for lab, h in power.items()})
    for lab, h in power.items():
        if after[lab].constant is False:
            out[lab] = ("still NOT constant", growth[lab])
        elif moved(flags[lab], h["tau"], h["mean"]):
            out[lab] = ("constant", growth[lab])
        else:
            out[lab] = ("not told apart", growth[lab])
    return out
