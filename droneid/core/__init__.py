"""Foundations no stage owns: the conventions (:mod:`.frames`: ENU world, FLU body, Z-Y-X Euler;
:mod:`.targets`: the derivatives droneid models), sympy expressions (:mod:`.expressions`),
numerics and least squares (:mod:`.numerics`, :mod:`.regression`, :mod:`.differentiation`),
constraint samples, words a person reads (:mod:`.text`), atomic file writes and TOML
(:mod:`.io_util`), lazy imports (:mod:`.lazy`) and plug-in discovery (:mod:`.plugins`).
Nothing here knows a log, a prior or a pipeline stage."""
