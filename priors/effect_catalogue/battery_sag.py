"""Battery sag: thrust per command falls with the battery voltage.

Feature (v̇x, v̇y, v̇z): G·(u/ū)·(V − V̄)/V̄, u the command (throttle, else the mean motor
command), ū and V̄ (V) training means, coefficient ``kappa`` -> relative thrust change per
relative voltage (1 = thrust proportional to voltage). Not applicable when G comes from measured
rotor speeds or thrust (they include the voltage already).

Precondition: the voltage falls by at least ``MIN_SAG`` (2 %, 2nd-98th percentile range over the
mean) during the training flights.
"""
import numpy as np
import sympy as sp

from droneid.core.expressions import symbol
from droneid.core.targets import TARGETS
from priors.effects import TILT, Effect, Interpretation, spread
from priors.thrust import motor_count

_CMD = ("throttle", "motor1")
MIN_SAG = 0.02


def _preconditions(ctx):
    v = np.asarray(ctx.columns["battery_voltage"], float)
    rel = spread(v) / max(abs(float(np.mean(v))), 1e-9)
    if rel < MIN_SAG:
        return f"the battery voltage varies by only {100 * rel:.1f} % (< {100 * MIN_SAG:g} %)"
    return None


def _command(available):
    """The collective COMMAND (what the battery's voltage scales into thrust): throttle, else
    the mean motor command; None without either."""
    have = set(available)
    if "throttle" in have:
        return "throttle", symbol("throttle")
    motors = [f"motor{i}" for i in range(1, motor_count(have).get("motor", 0) + 1)]   # motor1..N
    if motors:
        return "mean motor command", sp.Add(*[symbol(m) for m in motors]) / len(motors)
    return None


def _applicable(ctx):
    if ctx.tilt is not None and any(s.name == "battery_voltage" for s in ctx.tilt.free_symbols):
        return ("the prior's thrust already scales its commands with the battery voltage "
                "(identify's battery compensation, docs/priors.md)")
    if ctx.tilt is not None and ctx.tilt_role == "thrust" and any(
            s.name == "thrust" or s.name.startswith("rpm") for s in ctx.tilt.free_symbols):
        return ("the prior's thrust comes from measured rotor speeds or thrust, which already "
                "include the battery's voltage")
    return None


def _constants(ctx):
    _, u = _command(ctx.columns)
    return {"u_mean": float(np.mean(ctx.evaluate(u))),
            "V_mean": float(np.mean(ctx.columns["battery_voltage"]))}


def _features(ctx, k):
    _, u = _command(ctx.columns)
    ub, vb = k.get("u_mean", 0.0), k.get("V_mean", 0.0)
    if not (abs(ub) > 1e-9 and abs(vb) > 1e-9):
        return {}
    v = symbol("battery_voltage")
    return {"kappa": ctx.tilt * (u / sp.Float(ub)) * (v - sp.Float(vb)) / sp.Float(vb)}


def _interpret(coef, base):
    k = coef.get("kappa", float("nan"))
    return Interpretation(f"thrust per command changes by {k:.2f} × ΔV/V̄ (battery sag; "
                          "1 = thrust proportional to voltage)", {"kappa": k})


EFFECT = Effect("battery_sag", "thrust per command falls with battery voltage (needs a command and "
                "the voltage)", ((TILT,), _CMD, ("battery_voltage",)), _interpret,
                expr_fn=_features, constants_fn=_constants, applicable_fn=_applicable,
                data_fn=_preconditions, targets=tuple(TARGETS), explain_signal="battery_voltage",
                order=110)
