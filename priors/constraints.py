"""Formal constraints as data: what the identified model must do where the data say little.

A :class:`Constraint` is a domain (per input: a fixed value or an interval ``(lo, hi)``), a
relation (``eq``, ``le``, ``ge``) and a value ``c``: on every point of the domain the model must
satisfy ``f(x) = c`` (or ``<=``/``>=``). A :class:`ConstraintSet` groups the constraints of one
target; :meth:`ConstraintSet.sample` draws points uniformly over each domain and returns a
:class:`droneid.core.constraint_samples.ConstraintSamples` for the engine. Draw the training and the test
samples with different seeds (:meth:`ConstraintSet.train_test`; paper: 50 + 50 per constraint).

Inputs a constraint does not name are fixed at the set's ``defaults`` value, or 0 when the set
gives none (e.g. the paper's drone constraints name every input; a ``throttle`` input a user adds
is then held at 0 unless ``defaults = {throttle = 0.5}``).

Built-in sets (:func:`priors.registry.get_constraints`):

``paper`` for ``vx_dot`` / ``vy_dot`` (prior ``tilt-drag``): with vx = 0 (vy = 0), four
constraints each demanding zero acceleration: level in the tilt that does not act, yawed so the
other tilt acts across the axis (see :func:`paper_drone`).

``paper`` for ``x_dot`` / ``y_dot`` (prior ``unicycle``, the TurtleBot), three each: no motion
along the axis when ``v_f = 0``; and when heading across the axis (``yaw = ±π/2`` for ``x_dot``,
``yaw = 0, π`` for ``y_dot``) while not turning (``v_a = 0``). Our reading of the paper's text;
the ranges of the free inputs (``v_f`` ∈ [0, 0.3] m/s, ``v_a`` ∈ [−1, 1] rad/s, ``yaw`` ∈ [−π, π])
are our choice.

User sets come from TOML (:func:`load_constraints`)::

    target = "vx_dot"                 # default target of the constraints below
    [defaults]                        # optional: values of inputs no constraint names
    throttle = 0.5
    [[constraint]]
    name = "no drift when level"      # optional
    relation = "eq"                   # eq | le | ge  (default eq)
    value = 0.0                       # c (default 0)
    domain = { vx = 0, pitch = 0, roll = ["-pi/15", "pi/15"], yaw = 0 }

Domain values are numbers, numeric expressions as strings (``"pi/15"``, parsed safely), or
two-element lists ``[lo, hi]``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from droneid.core.constraint_samples import ConstraintSamples
from droneid.core.io_util import load_toml
from droneid.errors import ConfigError, MissingSignalError, did_you_mean
from droneid.core.expressions import parse_expression
from droneid.core.targets import HORIZONTAL, TARGETS, axis_of, velocity_of

#: the prior registry: its priors declare their constraint sets, so it imports this module


__all__ = ["Constraint", "ConstraintSet", "constraint_set", "load_constraints", "paper_drone",
           "paper_turtlebot", "rotor_thrust", "drag_sign", "extended", "CONSTRAINT_SETS"]

_RELATIONS = {"eq": "eq", "==": "eq", "=": "eq", "le": "le", "<=": "le", "ge": "ge", ">=": "ge"}


@dataclass(frozen=True)
class Constraint:
    """``f(x) <relation> value`` for every ``x`` in ``domain`` (input -> value or (lo, hi))."""
    name: str
    domain: Mapping[str, float | tuple[float, float]]
    relation: str = "eq"
    value: float = 0.0
    target: str = ""

    def __post_init__(self):
        where = f"constraint '{self.name}'" + (f" ({self.target})" if self.target else "")
        rel = _RELATIONS.get(self.relation) if isinstance(self.relation, str) else None
        if rel is None:
            raise ConfigError(f"{where}: relation must be eq, le or ge; got {self.relation!r}")
        if isinstance(self.value, bool) or not isinstance(self.value, (int, float)) \
                or not math.isfinite(self.value):
            raise ConfigError(f"{where}: value must be a finite number; got {self.value!r}")
        if not isinstance(self.domain, Mapping) or not self.domain:
            raise ConfigError(f"{where}: empty domain (name at least one input)")
        dom = {}
        for k, v in self.domain.items():
            if isinstance(v, (tuple, list)):
                if len(v) != 2:
                    raise ConfigError(f"{where}: domain of '{k}' must be a value or (lo, hi); got {v!r}")
                lo, hi = (_number(x, f"{where}: domain of '{k}'") for x in v)
                if lo > hi:
                    raise ConfigError(f"{where}: domain of '{k}' is empty: lo {lo:g} > hi {hi:g}")
                dom[str(k)] = (lo, hi) if lo < hi else lo
            else:
                dom[str(k)] = _number(v, f"{where}: domain of '{k}'")
        object.__setattr__(self, "relation", rel)
        object.__setattr__(self, "value", float(self.value))
        object.__setattr__(self, "domain", MappingProxyType(dom))

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self.domain)


def _number(x, where: str) -> float:
    if isinstance(x, str):
        expr = parse_expression(x, [], what=where)  # ConfigError for anything but arithmetic
        try:
            x = float(expr.evalf())
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: {x!r} is not a real number") from None
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise ConfigError(f"{where}: must be a finite number; got {x!r}")
    return float(x)


@dataclass(frozen=True)
class ConstraintSet:
    """The constraints of one target, plus values for inputs no constraint names."""
    target: str
    constraints: tuple[Constraint, ...]
    defaults: Mapping[str, float] = field(default_factory=dict)
    name: str = ""

    def __post_init__(self):
        cs = tuple(self.constraints)
        if not cs:
            raise ConfigError(f"constraint set '{self.name or self.target}' has no constraints")
        names = [c.name for c in cs]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ConfigError(f"constraint set '{self.name or self.target}': duplicate constraint "
                              f"name {sorted(dup)[0]!r}")
        for c in cs:
            if c.target and c.target != self.target:
                raise ConfigError(f"constraint '{c.name}' is for {c.target}, not {self.target}")
        defaults = {k: _number(v, f"constraint set '{self.name}': default of '{k}'")
                    for k, v in dict(self.defaults).items()}
        object.__setattr__(self, "constraints", cs)
        object.__setattr__(self, "defaults", MappingProxyType(defaults))

    def __len__(self) -> int:
        return len(self.constraints)

    @property
    def inputs(self) -> tuple[str, ...]:
        """Every input some constraint names (in order of first appearance)."""
        return tuple(dict.fromkeys(k for c in self.constraints for k in c.domain))

    def sample(self, input_names: Sequence[str], n_per_constraint: int = 50, seed=0
               ) -> ConstraintSamples:
        """``n_per_constraint`` points per constraint over ``input_names`` (the model's inputs, in
        the data's column order): named inputs uniform over their interval or fixed; others at
        ``defaults`` or 0. A constraint naming an input not in ``input_names`` raises
        MissingSignalError naming the constraint."""
        input_names = tuple(input_names)
        if isinstance(n_per_constraint, bool) or not isinstance(n_per_constraint, (int, np.integer)) \
                or n_per_constraint < 1:
            raise ConfigError(f"The 'n_per_constraint' parameter must be a positive integer. "
                              f"Got {n_per_constraint!r} instead.")
        for c in self.constraints:
            for k in c.domain:
                if k not in input_names:
                    raise MissingSignalError(
                        k, input_names, where=f"the model inputs (constraint '{c.name}' of "
                                              f"{self.name or 'the set'} for {self.target} names it)")
        rng = np.random.default_rng(seed)
        n = int(n_per_constraint)
        Xs, kind, bound, group = [], [], [], []
        for g, c in enumerate(self.constraints):
            X = np.empty((n, len(input_names)))
            for j, name in enumerate(input_names):
                v = c.domain.get(name, self.defaults.get(name, 0.0))
                X[:, j] = rng.uniform(v[0], v[1], n) if isinstance(v, tuple) else v
            Xs.append(X)
            kind.append(np.full(n, ConstraintSamples.kind_code(c.relation)))
            bound.append(np.full(n, c.value))
            group.append(np.full(n, g))
        return ConstraintSamples(np.vstack(Xs), np.concatenate(kind), np.concatenate(bound),
                                 np.concatenate(group), input_names,
                                 tuple(c.name for c in self.constraints))

    def train_test(self, input_names: Sequence[str], n_per_constraint: int = 50, seed=0
                   ) -> tuple[ConstraintSamples, ConstraintSamples]:
        """Training and test samples from two independent streams spawned from ``seed``."""
        s_train, s_test = np.random.SeedSequence(seed).spawn(2)
        return (self.sample(input_names, n_per_constraint, s_train),
                self.sample(input_names, n_per_constraint, s_test))


# -- built-in sets ------------------------------------------------------------------------------
def paper_drone(target: str) -> ConstraintSet:
    """The paper's four drone constraints for ``vx_dot`` or ``vy_dot`` (all demand 0).

    vx_dot, with vx = 0: (pitch = 0, roll ∈ [−π/15, π/15], yaw = 0), (pitch = 0, roll ∈ [−π/15,
    π/15], yaw = π), (pitch ∈ [−π/15, π/15], roll = 0, yaw = π/2), (pitch ∈ [−π/15, π/15],
    roll = 0, yaw = −π/2). vy_dot: the same with pitch and roll swapped and vy = 0.
    """
    a = math.pi / 15
    if target == "vx_dot":
        v, first, second = "vx", "pitch", "roll"
    elif target == "vy_dot":
        v, first, second = "vy", "roll", "pitch"
    else:
        raise ConfigError(f"the paper's drone constraints are for vx_dot and vy_dot, not {target!r}")
    doms = [
        (f"{first}=0, yaw=0", {first: 0.0, second: (-a, a), "yaw": 0.0}),
        (f"{first}=0, yaw=pi", {first: 0.0, second: (-a, a), "yaw": math.pi}),
        (f"{second}=0, yaw=pi/2", {first: (-a, a), second: 0.0, "yaw": math.pi / 2}),
        (f"{second}=0, yaw=-pi/2", {first: (-a, a), second: 0.0, "yaw": -math.pi / 2}),
    ]
    cs = tuple(Constraint(f"{target} = 0 at {v}=0, {label}",
                          {v: 0.0, "pitch": d["pitch"], "roll": d["roll"], "yaw": d["yaw"]},
                          "eq", 0.0, target) for label, d in doms)
    return ConstraintSet(target, cs, name="paper")


def paper_turtlebot(target: str) -> ConstraintSet:
    """Three TurtleBot (unicycle) constraints for ``x_dot`` or ``y_dot`` (all demand 0)."""
    vf, va, yaw = (0.0, 0.3), (-1.0, 1.0), (-math.pi, math.pi)
    if target == "x_dot":
        across = (math.pi / 2, -math.pi / 2)
    elif target == "y_dot":
        across = (0.0, math.pi)
    else:
        raise ConfigError(f"the paper's TurtleBot constraints are for x_dot and y_dot, not {target!r}")
    cs = [Constraint(f"{target} = 0 when v_f = 0", {"v_f": 0.0, "v_a": va, "yaw": yaw}, "eq", 0.0, target)]
    for h in across:
        cs.append(Constraint(f"{target} = 0 at yaw = {h:.4g}, v_a = 0",
                             {"yaw": h, "v_a": 0.0, "v_f": vf}, "eq", 0.0, target))
    return ConstraintSet(target, tuple(cs), name="paper")


def rotor_thrust(target: str, thrust_signals: Mapping[str, float], g: float = 9.81) -> ConstraintSet:
    """Constraints of the rotor-thrust prior for ``vx_dot``, ``vy_dot`` or ``vz_dot``.

    ``thrust_signals`` maps each thrust input (``rpm1``.., ``motor1``.., ``throttle`` or
    ``thrust``) to the largest value the vehicle reaches (from the training data). With the
    vehicle at rest (v = 0):

    * no thrust (every thrust input 0), any tilt up to 30°, any yaw: v̇ = −g e3 (free fall);
    * level (roll = pitch = 0), any thrust and yaw: no horizontal acceleration;
    * tilted only across the axis (vx_dot: pitch = 0, yaw = 0, roll within ±30°; vy_dot: roll = 0,
      yaw = 0, pitch within ±30°), any thrust: none along it (the thrust has no component there).
    """
    axis = axis_of(target)
    if axis is None:
        raise ConfigError(f"the rotor-thrust constraints are for {', '.join(TARGETS)}, not {target!r}")
    if not thrust_signals:
        raise ConfigError("the rotor-thrust constraints need at least one thrust input")
    a, v = math.pi / 6, velocity_of(target)
    zero = {s: 0.0 for s in thrust_signals}
    span = {s: (0.0, float(hi)) for s, hi in thrust_signals.items()}
    cs = [Constraint(f"{target} = {'-g' if axis == 'z' else '0'} with no thrust at rest",
                     {v: 0.0, **zero, "roll": (-a, a), "pitch": (-a, a), "yaw": (-math.pi, math.pi)},
                     "eq", -g if axis == "z" else 0.0, target)]
    if axis != "z":
        cs.append(Constraint(f"{target} = 0 when level at rest",
                             {v: 0.0, **span, "roll": 0.0, "pitch": 0.0, "yaw": (-math.pi, math.pi)},
                             "eq", 0.0, target))
        across = {"roll": (-a, a), "pitch": 0.0} if axis == "x" else {"roll": 0.0, "pitch": (-a, a)}
        cs.append(Constraint(f"{target} = 0 when tilted across the axis at rest",
                             {v: 0.0, **span, **across, "yaw": 0.0}, "eq", 0.0, target))
    return ConstraintSet(target, tuple(cs), name="rotor-thrust")


def drag_sign(target: str, v_max: float, level: Mapping[str, float | tuple] | None = None) -> tuple:
    """Constraints that reach beyond v = 0: level (roll = pitch = 0) and moving along the axis at
    up to ``v_max`` m/s (1.5 x the training speed, say), the vehicle decelerates:
    ``v̇ ≤ 0`` for v ∈ [0.1 v_max, v_max] and ``v̇ ≥ 0`` for v ∈ [−v_max, −0.1 v_max]. Drag opposes
    motion; a model whose evolved terms turn over or blow up outside the data breaks them.
    ``level`` gives further inputs' domains (e.g. the thrust inputs' span)."""
    axis = velocity_of(target) if target in HORIZONTAL else None
    if axis is None:
        raise ConfigError(f"the drag-sign constraints are for vx_dot and vy_dot, not {target!r}")
    if not (isinstance(v_max, (int, float)) and math.isfinite(v_max) and v_max > 0):
        raise ConfigError(f"drag_sign: v_max must be a positive number of m/s; got {v_max!r}")
    dom = {"roll": 0.0, "pitch": 0.0, "yaw": (-math.pi, math.pi), **dict(level or {})}
    return (Constraint(f"{target} <= 0 when level and moving along +{axis[1]}",
                       {**dom, axis: (0.1 * v_max, v_max)}, "le", 0.0, target),
            Constraint(f"{target} >= 0 when level and moving along -{axis[1]}",
                       {**dom, axis: (-v_max, -0.1 * v_max)}, "ge", 0.0, target))


def extended(base: ConstraintSet, v_max: float, level: Mapping[str, float | tuple] | None = None
             ) -> ConstraintSet:
    """``base`` plus the drag-sign constraints (:func:`drag_sign`) for its target, if it has them."""
    if base.target not in HORIZONTAL:
        return base
    return ConstraintSet(base.target, base.constraints + drag_sign(base.target, v_max, level),
                         base.defaults, name=f"{base.name}+drag-sign")


#: set name -> {prior name -> factory(target)}; a prior names its set (``PriorModel.constraints``)
CONSTRAINT_SETS = {"paper": {"tilt-drag": paper_drone, "unicycle": paper_turtlebot}}


def constraint_set(name: str, prior: str, target: str) -> ConstraintSet:
    """The built-in constraint set ``name`` of the built-in prior ``prior`` for ``target``
    (:func:`priors.registry.get_constraints` finds the prior from the target when it is not named)."""
    if name not in CONSTRAINT_SETS:
        raise ConfigError(f"unknown constraint set {name!r}{did_you_mean(str(name), CONSTRAINT_SETS)}; "
                          f"built-in sets: {', '.join(CONSTRAINT_SETS)} (user sets: load_constraints(path))")
    by_prior = CONSTRAINT_SETS[name]
    if prior not in by_prior:
        raise ConfigError(f"constraint set {name!r} has nothing for prior {prior!r}"
                          f"{did_you_mean(str(prior), by_prior)}; priors: {', '.join(by_prior)}")
    return by_prior[prior](target)


def load_constraints(path, target: str | None = None) -> ConstraintSet:
    """A user constraint set from TOML (format in the module docstring). ``target`` selects
    the constraints of one target when the file has several; it is required then."""
    path = Path(path)
    data = load_toml(path, "constraints file")
    return constraints_from_dict(data, target=target, where=str(path))


def constraints_from_dict(data: dict, target: str | None = None, where: str = "constraints"
                          ) -> ConstraintSet:
    """The constraint set of a parsed TOML document (see :func:`load_constraints`)."""
    allowed = {"target", "defaults", "constraint", "name"}
    bad = [k for k in data if k not in allowed]
    if bad:
        raise ConfigError(f"{where}: unknown key {bad[0]!r}{did_you_mean(bad[0], allowed)}; "
                          f"allowed: {', '.join(sorted(allowed))}")
    default_target = data.get("target")
    items = data.get("constraint")
    if not isinstance(items, list) or not items:
        raise ConfigError(f"{where}: no [[constraint]] entries")
    parsed = []
    for i, c in enumerate(items):
        label = c.get("name", f"#{i + 1}") if isinstance(c, dict) else f"#{i + 1}"
        ctx = f"{where}: constraint '{label}'"
        if not isinstance(c, dict):
            raise ConfigError(f"{ctx}: must be a table")
        keys = {"name", "target", "relation", "value", "domain"}
        bad = [k for k in c if k not in keys]
        if bad:
            raise ConfigError(f"{ctx}: unknown key {bad[0]!r}{did_you_mean(bad[0], keys)}; "
                              f"allowed: {', '.join(sorted(keys))}")
        tgt = c.get("target", default_target)
        if not isinstance(tgt, str) or not tgt:
            raise ConfigError(f"{ctx}: no target (set target = \"vx_dot\" at the top or in the constraint)")
        dom = c.get("domain")
        if not isinstance(dom, dict):
            raise ConfigError(f"{ctx}: domain must be a table such as {{ vx = 0, roll = [-0.2, 0.2] }}")
        try:
            value = _number(c.get("value", 0.0), f"{ctx}: value")
            parsed.append(Constraint(str(label), dom, c.get("relation", "eq"), value, tgt))
        except ConfigError as exc:
            msg = str(exc)
            raise ConfigError(msg if msg.startswith(where) else f"{where}: {msg}") from None
    targets = list(dict.fromkeys(c.target for c in parsed))
    if target is None:
        if len(targets) > 1:
            raise ConfigError(f"{where}: constraints for several targets ({', '.join(targets)}); "
                              "choose one")
        target = targets[0]
    chosen = tuple(c for c in parsed if c.target == target)
    if not chosen:
        raise ConfigError(f"{where}: no constraints for {target!r}{did_you_mean(target, targets)}; "
                          f"the file has {', '.join(targets)}")
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        raise ConfigError(f"{where}: defaults must be a table of numbers")
    try:
        return ConstraintSet(target, chosen, defaults, name=data.get("name", Path(where).stem))
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
