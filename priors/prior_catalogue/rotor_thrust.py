"""``rotor-thrust``: logged thrust along the body z axis, gravity and linear drag (see
:func:`rotor_thrust`); the thrust terms come from :mod:`priors.thrust`.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from droneid.errors import ConfigError
from droneid.core.expressions import symbol
from droneid.core.targets import TARGETS

from .. import constraints as pc
from ..base import PriorFeature, PriorModel, check_param
from ..thrust import COMMAND_SOURCES, NOMINAL_EXPO, RPM_SCALE, THRUST_SOURCES, body_z_world, thrust_columns

#: the prior's name and its place among the built-in priors
NAME, ORDER = "rotor-thrust", 20


def rotor_thrust(source: str = "rpm", motors: int = 4, k_T: float = 0.0257, k_D: float = 0.28,
                 g: float = 9.81, rotor_drag: bool = False, expo: float = NOMINAL_EXPO,
                 v_ref: float | None = None, spin_min: float = 0.0, spin_max: float = 1.0,
                 rpm_unit: str = "rpm") -> PriorModel:
    """Rotor-thrust quadrotor model: logged thrust along the body z axis, gravity, linear drag::

        v̇ = (k_T · thrust(source)) R(roll, pitch, yaw) e3 − g e3 − k_D v   (world ENU)

    ``thrust(source)`` from :data:`THRUST_SOURCES` (``rpm``: Σ(ω_i/10⁴)²). The exact rotation,
    no hover-balance or small-angle assumption, so it models v̇z too. ``k_T`` (m/s² per unit of
    the thrust term: for ``rpm`` per (10⁴ rpm)²) is the nominal scale of the 1-feature form;
    split into terms (the default), least squares tunes every scale. ``rotor_drag`` adds the
    rotor-drag law −k_r (Σ ω_i/10⁴) v (blade flapping and induced drag grow with rotor speed).
    ``rpm_unit``: ``erpm`` when the log's motor speeds are electrical rpm (the descriptions say
    per (10⁴ erpm)²; the pole-pair factor is left to the fitted scale).
    A command source (``motor``, ``throttle``) maps its commands through the thrust curve
    (1 − e)u + e u² of shape ``expo`` e (:func:`priors.thrust.thrust_curve`; identify chooses e
    from the training flights, :mod:`droneid.fitting.thrust_curve`), and with ``v_ref`` (V) scales them by
    the battery voltage, u·V/v_ref; ``spin_min``/``spin_max``: the commands (0..1) where the curve
    starts and ends (ArduPilot's MOT_SPIN_MIN/MAX), u = (command − spin_min)/(spin_max − spin_min).
    All are ignored for ``rpm`` and ``thrust``.
    """
    if rpm_unit not in ("rpm", "erpm"):
        raise ConfigError(f"The 'rpm_unit' parameter of prior 'rotor-thrust' must be 'rpm' or 'erpm'. "
                          f"Got {rpm_unit!r} instead.")
    for name, v in (("k_T", k_T), ("k_D", k_D), ("g", g)):
        check_param("rotor-thrust", name, v)
    if not isinstance(motors, int) or isinstance(motors, bool) or not 1 <= motors <= 16:
        raise ConfigError(f"The 'motors' parameter of prior 'rotor-thrust' must be an integer in 1..16. "
                          f"Got {motors!r} instead.")
    command = source in COMMAND_SOURCES
    if command:
        check_param("rotor-thrust", "expo", expo)
        if not 0.0 <= expo <= 1.0:
            raise ConfigError(f"The 'expo' parameter of prior 'rotor-thrust' must be in [0, 1]. Got {expo!r} instead.")
        if v_ref is not None and not check_param("rotor-thrust", "v_ref", v_ref) > 0:
            raise ConfigError(f"The 'v_ref' parameter of prior 'rotor-thrust' must be > 0 V. Got {v_ref!r} instead.")
        for name, v in (("spin_min", spin_min), ("spin_max", spin_max)):
            check_param("rotor-thrust", name, v)
        if not 0.0 <= spin_min < spin_max <= 1.0:
            raise ConfigError(f"The 'spin_min'/'spin_max' parameters of prior 'rotor-thrust' must satisfy "
                              f"0 <= spin_min < spin_max <= 1. Got {spin_min!r}, {spin_max!r} instead.")
    cols = (thrust_columns(source, motors, expo, v_ref, (spin_min, spin_max)) if command
            else thrust_columns(source, motors, rpm_unit=rpm_unit))
    roll, pitch, yaw = (symbol(n) for n in ("roll", "pitch", "yaw"))
    b = dict(zip("xyz", body_z_world(roll, pitch, yaw)))
    signals = sorted({s.name for _, e, _ in cols for s in e.free_symbols},
                     key=lambda n: (len(n), n))
    terms, inputs = {}, {}
    for tgt in TARGETS.values():
        axis, v = tgt.axis, symbol(tgt.velocity)
        feats = [PriorFeature(f"{cname}_{axis}", sp.Float(k_T) * e * b[axis],
                              f"{THRUST_SOURCES[source][2].split(':')[0]} ({cname}) along world {axis}, "
                              f"nominal k_T = {k_T:.4g} {unit}; the fitted coefficient is a scale on it "
                              f"(1 = nominal)", "thrust", magnitude=sp.Float(k_T) * e)
                 for cname, e, unit in cols]
        if axis == "z":
            feats.append(PriorFeature("minus_g", sp.Float(-g), "gravity, m/s²", "gravity"))
        feats.append(PriorFeature(f"minus_kD_v{axis}", -sp.Float(k_D) * v, f"linear drag along world {axis}",
                                  "drag"))
        if rotor_drag and source == "rpm":
            s1 = sp.Add(*[symbol(f"rpm{i}") / RPM_SCALE for i in range(1, motors + 1)])
            feats.append(PriorFeature(f"rotor_drag_{axis}", -sp.Float(0.01) * s1 * v,
                                      f"rotor drag −k_r Σ(ω/10⁴) v{axis}", "drag"))
        terms[tgt.name] = tuple(feats)
        inputs[tgt.name] = (tgt.velocity, "roll", "pitch", "yaw", *signals)
    return PriorModel(
        "rotor-thrust",
        f"Rotor-thrust model: {THRUST_SOURCES[source][2]}, along the body z axis rotated by the "
        f"full attitude, minus gravity, minus linear drag k_D v.",
        terms, inputs, {"source": source, "motors": motors, "k_T": k_T, "k_D": k_D, "g": g,
                        "rotor_drag": rotor_drag, **({"rpm_unit": rpm_unit} if rpm_unit != "rpm" else {}),
                        **({"expo": float(expo), "v_ref": v_ref, "spin_min": float(spin_min),
                            "spin_max": float(spin_max)} if command else {})},
        vehicle="multirotor", constraints=span_constraints,
        # free fall at zero thrust: gravity is the only constant (known, fixed), no free one
        intercept={t: (0.0, 0.0) for t in terms}, hover_param="k_T", factory=rotor_thrust)


def span_constraints(prior: PriorModel, target: str, columns) -> tuple:
    """The rotor-thrust constraint set of ``target`` (:func:`priors.constraints.rotor_thrust`)
    over the thrust inputs' span in the training data (0 to their largest value), and that span
    as the level of the drag-sign constraints added to it."""
    span = {s: float(np.max(columns[s])) for s in prior.thrust_signals(target)}
    cs = pc.rotor_thrust(target, span, g=float(prior.params.get("g", 9.81)))
    return cs, {s: (0.0, v) for s, v in span.items()}


FACTORY = rotor_thrust
