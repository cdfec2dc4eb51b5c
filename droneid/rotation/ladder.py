"""The rotational ladder's decisions (issues 28, 37.2, 37.4): each body axis climbs held → rate
decay → [attitude spring: roll, pitch] → [spin-up reaction: yaw] → torque model on
:mod:`droneid.fitting.decide`'s one calibrated rule, with the (held-out training flight, regime) cells
of :func:`droneid.rotation.choice.select_rotation`'s leave-one-flight-out open-loop validation as
the units. Errors are body-rate SimErr of one axis
(Σ_{h=1..50} |Δω_k|, rad/s) per validation window.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from droneid.fitting.decide import decide_units, holm_step_down
from droneid.rotation.decay import regime_of

__all__ = ["climb", "AXES"]

#: the body axes, in the order of the rotational targets
AXES = ("roll", "pitch", "yaw")


def _ladder_steps(rungs: Sequence[str], k: int) -> list[tuple[str, str]]:
    """Axis ``k``'s steps, ``(rung, rung directly below it)``: each rung of ``rungs`` above
    ``held`` (``attitude`` is skipped on yaw: no level to return to; ``spinup`` on roll and pitch:
    the rotors' spin-up reaction is about z)."""
    own = _own(rungs, k)
    return list(zip(own[1:], own[:-1]))


def _cells(folds: list[dict], k: int, rung: str, against: str, regimes: int, min_windows: int = 3) -> dict:
    """The (held-out flight, regime) cells of one step of axis ``k``: the regimes are quantiles of
    the held body-rate error of the axis pooled over the folds (calm to hard), a cell counts when
    it has at least ``min_windows`` windows. Returns per counted cell the mean SimErr of the axis
    (rad/s) without (``against``) and with ``rung`` and its windows, and for the record ``wins``
    per flight and regime (None: too few windows) and ``ratio`` per regime (pooled over the flights)."""
    held = np.concatenate([f["errs"]["held"]["axis"][:, k] for f in folds])
    without, with_, windows, wins = [], [], [], []
    for f in folds:
        cls = regime_of(f["errs"]["held"]["axis"][:, k], regimes, held)
        new, old = f["errs"][rung]["axis"][:, k], f["errs"][against]["axis"][:, k]
        row = []
        for q in range(regimes):
            n = int((cls == q).sum())
            if n < min_windows:
                row.append(None)
                continue
            e0, e1 = float(old[cls == q].mean()), float(new[cls == q].mean())
            without.append(e0)
            with_.append(e1)
            windows.append(n)
            row.append(bool(e1 < e0))
        wins.append(row)
    cls = regime_of(held, regimes)
    new = np.concatenate([f["errs"][rung]["axis"][:, k] for f in folds])
    old = np.concatenate([f["errs"][against]["axis"][:, k] for f in folds])
    ratio = [float(new[cls == q].mean() / old[cls == q].mean()) if (cls == q).any() and old[cls == q].mean() > 0
             else None for q in range(regimes)]
    return {"without": np.array(without), "with": np.array(with_), "windows": np.array(windows), "wins": wins,
            "ratio": ratio}


def climb(folds: list[dict], rungs: Sequence[str], regimes: int, alpha: float,
               min_effect_pct: float) -> tuple[list[str], list[list[dict]], int]:
    """Every axis's ladder (:func:`select_rotation`) on the one calibrated rule of
    :mod:`droneid.fitting.decide`. Each step, a rung against the rung the axis stands on below it, is
    decided by :func:`droneid.fitting.decide.decide_units` on its (flight, regime) cells (:func:`_cells`),
    with Holm's step-down over every step of every axis (:func:`droneid.fitting.decide.holm_step_down`;
    family: every axis's steps, :func:`_ladder_steps`). An axis takes a rung when its step is accepted;
    a rung not taken leaves the next one to be tested against the rung below it. Which rung an
    axis stands on depends on the decisions, so they are made again with the comparisons they
    imply until nothing changes (first round: each rung against the one directly below; at most
    one round per rung). ``folds``: one per held-out flight, ``{"name", "errs": {rung: {"axis":
    (W, 3) SimErr per window and axis}}}`` with ``held`` and every rung of ``rungs``. Returns (the
    rung per axis, per axis one record per step, the family size)."""
    plan = {(k, rung): below for k in range(3) for rung, below in _ladder_steps(rungs, k)}
    m = len(plan)
    cache: dict = {}

    def cells(key, against):
        if (key, against) not in cache:
            cache[(key, against)] = _cells(folds, key[0], key[1], against, regimes)
        return cache[(key, against)]

    def name(key):
        return f"{AXES[key[0]]} {key[1]} vs {plan[key]}"

    for _ in range(len(rungs) + 1):
        testable = [key for key in plan if cells(key, plan[key])["without"].size >= 3]
        decisions = holm_step_down(
            lambda key, rank: decide_units(cells(key, plan[key])["without"], cells(key, plan[key])["with"],
                                           cells(key, plan[key])["windows"], alpha=alpha, family_size=m, rank=rank,
                                           min_effect_pct=min_effect_pct, loss="simerr", what=name(key)),
            testable) if testable else {}
        choice, implied = [], {}
        for k in range(3):
            current = "held"
            for rung, _ in _ladder_steps(rungs, k):
                implied[(k, rung)] = current
                dec = decisions.get((k, rung))
                if dec is not None and dec.accepted and plan[(k, rung)] == current:
                    current = rung
            choice.append(current)
        if implied == plan:
            break
        plan = implied
    records = []
    for k in range(3):
        steps = []
        for rung, _ in _ladder_steps(rungs, k):
            key = (k, rung)
            c, dec = cells(key, plan[key]), decisions.get(key)
            st = {"rung": rung, "against": plan[key], "wins": c["wins"], "ratio": c["ratio"],
                  "cells": int(c["without"].size)}
            if dec is None:
                st.update({"p_value": None, "threshold": None, "effect_pct": None, "rank": None, "accepted": False,
                           "evidence": f"{name(key)}: fewer than 3 (flight, regime) cells with 3 windows or more: "
                                       f"not tested"})
            else:
                st.update({"p_value": dec.p_value, "threshold": dec.threshold, "effect_pct": dec.effect_pct,
                           "rank": dec.rank, "accepted": dec.accepted, "evidence": dec.evidence})
            st["taken"] = bool(st["accepted"] and choice[k] in _ladder_from(rungs, k, rung))
            steps.append(st)
        records.append(steps)
    return choice, records, m


def _ladder_from(rungs: Sequence[str], k: int, rung: str) -> tuple[str, ...]:
    """``rung`` and the rungs above it on axis ``k``'s ladder."""
    own = _own(rungs, k)
    return tuple(own[own.index(rung):])


def _own(rungs: Sequence[str], k: int) -> list[str]:
    """The rungs of ``rungs`` on axis ``k``'s ladder: ``attitude`` on roll and pitch only,
    ``spinup`` on yaw only."""
    return [r for r in rungs if not ((r == "attitude" and k == 2) or (r == "spinup" and k < 2))]
