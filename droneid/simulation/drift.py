"""The verdict of an open-loop table, for people: does the identified vehicle drift less than the
state held and than nominal physics (identify's text and report, predict's text and JSON say it
alike; the table itself is :func:`droneid.simulation.openloop.open_loop`'s)."""
from __future__ import annotations

import math
from collections.abc import Mapping

from droneid.core.numerics import to_float

__all__ = ["open_loop_verdict"]


def open_loop_verdict(ol: Mapping, rotation: bool = True) -> str:
    """The open-loop table's verdict, one sentence first: whether the identified vehicle drifts
    less than holding the state ("constant") and than nominal physics, by position SimErr (m),
    and, where it drifts further than the state held, up to which horizon it is still better and
    whether its attitude is what drifts (``rotation``: whether it has a rotational model; with the
    body rates held no simulation from the motors keeps the attitude). "" without the rows.
    ``ol``: {model: {steps | "simerr": {quantity: MAE}}} as :meth:`droneid.use.score.Score.open_loop_table`
    gives it (identify's text and report, predict's text and JSON say it alike)."""
    ident, const = ol.get("identified"), ol.get("constant")
    if not ident or not const or "simerr" not in ident or "simerr" not in const:
        return ""
    a, c = to_float(ident["simerr"].get("position")), to_float(const["simerr"].get("position"))
    if not (math.isfinite(a) and math.isfinite(c)):
        return ""
    nom = ol.get("nominal physics")
    n = to_float(nom["simerr"].get("position")) if nom and "simerr" in nom else math.nan
    beside = f" and {n:.3g} for nominal physics" if math.isfinite(n) else ""
    if a < c and not a >= n:
        return (f"open loop: the identified vehicle drifts least (position SimErr {a:.3g} m against {c:.3g} for the "
                f"state held{beside})")
    if a < c:
        return (f"open loop: the identified vehicle drifts less than the state held (position SimErr {a:.3g} m "
                f"against {c:.3g}) but MORE than nominal physics ({n:.3g})")
    steps = sorted(int(h) for h in ident if h.isdigit() and h in const)
    good = [h for h in steps if to_float(ident[str(h)].get("position")) < to_float(const[str(h)].get("position"))]
    upto, worse = 0, None
    for h in steps:
        if h not in good:
            worse = h
            break
        upto = h
    when = (f"it is the better prediction up to {upto} steps, not at {worse}" if upto and worse else
            "it is no better at any horizon shown" if not upto else
            "it is better at each horizon shown, not summed over 1..50 steps")
    out = (f"open loop: the identified vehicle drifts FURTHER than the state held (position SimErr {a:.3g} m "
           f"against {c:.3g} for the state held{beside}); {when}")
    ia, ca = to_float(ident["simerr"].get("attitude")), to_float(const["simerr"].get("attitude"))
    if not rotation and ia > ca:
        out += (f"; its attitude drifts (attitude SimErr {ia:.3g} rad against {ca:.3g} held): its body rates are "
                f"held (no rotational model), so from the motors alone nothing keeps the attitude: do not "
                f"simulate this vehicle open loop beyond that horizon")
    return out
