"""The one classical Runge-Kutta (RK4) step droneid integrates with: the simulator, open-loop
state integration (:mod:`.openloop`) and multi-step rollouts (:mod:`.rollout`) all step through
:func:`rk4_step`. (The exported vehicle's Python and C code carry their own copy of the same
tableau: an exported file runs without droneid.)

The caller owns the state's arithmetic, so one step serves numpy arrays, dicts of arrays and
plain lists alike, and a caller can renormalise a quaternion at every stage.
"""
from __future__ import annotations

from collections.abc import Callable

__all__ = ["rk4_step", "axpy", "combine"]


def axpy(x, h: float, k):
    """``x + h·k`` (numpy arrays or floats)."""
    return x + h * k


def combine(x, h: float, k1, k2, k3, k4):
    """The RK4 update ``x + h·(k1 + 2 k2 + 2 k3 + k4)`` with ``h = dt/6`` (numpy arrays)."""
    return x + h * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def rk4_step(deriv: Callable, x, dt: float, *, stage: Callable = axpy, update: Callable = combine,
             k1=None):
    """The state after one RK4 step of ``dt`` seconds.

    ``deriv(x, at)`` is ẋ at state ``x``; ``at`` says where in the step its inputs are taken: 0 at
    the start, 1 at the midpoint (the second and third stages), 2 at the end. ``stage(x, h, k)``
    is the stage state ``x + h·k`` and ``update(x, dt/6, k1, k2, k3, k4)`` the step's result, both
    in the caller's arithmetic. ``k1``: ẋ at the start when the caller has it already.
    """
    if k1 is None:
        k1 = deriv(x, 0)
    k2 = deriv(stage(x, 0.5 * dt, k1), 1)
    k3 = deriv(stage(x, 0.5 * dt, k2), 1)
    k4 = deriv(stage(x, dt, k3), 2)
    return update(x, dt / 6.0, k1, k2, k3, k4)
