"""The targets droneid models, in one table.

A target is the time derivative of a state signal, named ``<signal>_dot``. The vehicle targets
identify, diagnose, predict and rollout work on are the three world-frame accelerations (ENU,
m/s²): ``vx_dot``, ``vy_dot``, ``vz_dot``. Each row says which world axis it acts along, which
velocity (m/s) and position (m) signals belong to that axis, whether it is horizontal (where
drag-sign constraints and the horizontal effects apply) and the inputs the paper gives a model
of it when the user names none (``throttle`` for ``vz_dot`` only when the flights have it).

Other priors may model other targets (the ground robot's unicycle: ``x_dot``, ``y_dot``); those
follow the same naming rule (:func:`state_of`) but have no row here.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

from droneid.errors import ConfigError, did_you_mean

__all__ = ["Target", "TARGETS", "HORIZONTAL", "get_target", "state_of", "axis_of", "velocity_of",
           "by_velocity", "targets_for"]


@dataclass(frozen=True)
class Target:
    """One world-frame acceleration target (m/s²)."""
    name: str                 # "vx_dot"
    axis: str                 # ENU world axis: "x", "y" or "z"
    velocity: str             # the velocity signal it is the derivative of (m/s): "vx"
    position: str             # the position signal along the same axis (m): "x"
    horizontal: bool          # True for x and y
    paper_inputs: tuple       # default inputs (the paper's choice)


#: name -> Target, in axis order
TARGETS = MappingProxyType({t.name: t for t in (
    Target("vx_dot", "x", "vx", "x", True, ("vx", "pitch", "roll", "yaw")),
    Target("vy_dot", "y", "vy", "y", True, ("vy", "pitch", "roll", "yaw")),
    Target("vz_dot", "z", "vz", "z", False, ("vz", "roll", "pitch", "throttle")),
)})
#: the horizontal targets' names
HORIZONTAL = tuple(t.name for t in TARGETS.values() if t.horizontal)


def get_target(name: str) -> Target:
    """The row of ``name``; ConfigError naming the known targets otherwise."""
    try:
        return TARGETS[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown target {name!r}{did_you_mean(str(name), TARGETS)}; "
                          f"known targets: {', '.join(TARGETS)}") from None


def state_of(target: str) -> str:
    """The signal a target is the time derivative of: ``vx_dot`` -> ``vx``, ``x_dot`` -> ``x``."""
    return target[:-4] if target.endswith("_dot") else target


def axis_of(target: str) -> str | None:
    """The world axis letter of a vehicle target, None for other targets."""
    t = TARGETS.get(target)
    return t.axis if t else None


def velocity_of(target: str) -> str | None:
    """The velocity signal of a vehicle target's axis (``vx_dot`` -> ``vx``), None for others."""
    t = TARGETS.get(target)
    return t.velocity if t else None


def targets_for(prior, requested=None) -> tuple[str, ...]:
    """The vehicle targets to model with ``prior`` (anything with ``name`` and ``targets``):
    ``requested`` when given (each must be one the prior models), else every vehicle target the
    prior models, in table order. ConfigError naming the prior and what it models otherwise."""
    name, has = getattr(prior, "name", "prior"), tuple(getattr(prior, "targets", ()))
    targets = tuple(requested) if requested else tuple(t for t in TARGETS if t in has)
    if not targets:
        raise ConfigError(f"prior '{name}' models none of {', '.join(TARGETS)}")
    for t in targets:
        if t not in has:
            raise ConfigError(f"prior '{name}' has no model of {t}; it models "
                              f"{', '.join(has)} (choose another --prior or --target)")
    return targets


def by_velocity(signal: str) -> Target | None:
    """The target whose velocity signal is ``signal`` (``vx`` -> the ``vx_dot`` row), or None."""
    return next((t for t in TARGETS.values() if t.velocity == signal), None)
