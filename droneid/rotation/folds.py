"""Leave-one-flight-out fits of the rotational choice by downdating (issue 38): the models
:func:`droneid.rotation.choice.select_rotation` validates on each held-out flight, from sums
over the flights computed once, so that the choice's cost grows with the flights, not with their
square.

The rule, the one :func:`droneid.core.regression.blocked_cv` follows: the robust (Huber) weights are
those of the fit on EVERY training flight (one IRLS), and each fold is one weighted bounded least
squares on the statistics of all flights minus the held-out flight's (:func:`droneid.core.regression.gram`
sums): the weights are a property of the training rows, a fold's fit never sees the held-out
flight's rows through its coefficients. A refit from scratch per fold (an IRLS on F − 1 flights,
F times) costs F² flights' rows.

The balance prior of the torque inputs (:func:`droneid.rotation.model.balanced`: the training flights'
mean ``s``) differs per fold; the design is affine in it (``s = s₀ − h ⊗ prior`` with ``h =
w/(n + w)``), so each flight's statistics are kept for ``s₀`` and for the prior's response
columns, and a fold's design is a linear map of them (exact: no row is recomputed). Rates in
rad/s, accelerations m/s² (translation) and rad/s² (rotation).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from priors.torque import RotorLayout

from droneid.errors import DataError
from droneid.simulation.openloop import StateLog
from droneid.core.regression import (gram_bounded_lstsq, group_grams, group_intercepts, robust_fit, robust_fit_grouped,
                         unit_grams, within_gram)
from droneid.rotation.model import (RotationModel, TranslationModel, flying_mask, rotation_bounds, rotation_design,
                       rotation_rows)

__all__ = ["translation_folds", "rotation_folds", "downdatable"]


def translation_folds(rows: Sequence[tuple[np.ndarray, np.ndarray] | None], names: Sequence[str], *,
                      delay_steps: int = 0, rad_s_per_rpm: float) -> dict[str, TranslationModel]:
    """{flight name: the :class:`TranslationModel` (drag fitted) of every other flight}, from the
    logs' :func:`droneid.rotation.model.translation_rows` ``rows`` (one per log, ``names`` their flights'
    names) by downdating (module docstring): k_T ≥ 0 and drag ≥ 0 as
    :func:`droneid.rotation.model.fit_translation_rows`."""
    keep = [i for i, r in enumerate(rows) if r is not None]
    if not keep:
        raise DataError("fit_translation: no training row with every motor turning in flight")
    A = np.vstack([rows[i][0] for i in keep])
    y = np.concatenate([rows[i][1] for i in keep])
    unit = np.concatenate([np.full(rows[i][1].size, i) for i in keep])
    lo = np.zeros(A.shape[1])
    ids, S, _ = unit_grams(A, y, robust_fit(A, y, lo=lo).weights, unit)
    out = {}
    for name in dict.fromkeys(names):
        mine = np.array([names[i] == name for i in ids])
        if mine.all():
            raise DataError(f"fit_translation: no training row with every motor turning in flight besides {name}")
        beta = gram_bounded_lstsq(S[~mine].sum(axis=0), lo)
        out[name] = TranslationModel(float(beta[0]), np.asarray(beta[1:4]), int(delay_steps), float(rad_s_per_rpm))
    return out


def downdatable(candidate: dict) -> bool:
    """Whether :func:`rotation_folds` fits this torque candidate of
    :func:`droneid.rotation.choice.select_rotation`: the equation-error fit
    (:func:`droneid.rotation.model.fit_rotation`) without the ``attitude`` term (its level is a median
    of the training flights: no sum to downdate). Others are refitted per fold."""
    return candidate.get("method", "equation") == "equation" and "attitude" not in candidate.get("terms", ())


def rotation_folds(logs: Sequence[StateLog], layout: RotorLayout, candidate: dict, *, window_s: float,
                   rad_s_per_rpm: float) -> dict[str, RotationModel]:
    """{flight name: :func:`droneid.rotation.model.fit_rotation` with ``candidate``'s keywords on every
    other flight}, by downdating (module docstring): one trim per training log, the balance prior
    the training logs' mean ``s`` in flight. ``candidate`` must be :func:`downdatable`."""
    if not downdatable(candidate):
        raise DataError(f"rotation_folds: candidate {candidate!r} cannot be downdated")
    c = dict(candidate)
    c.pop("method", None)
    terms = tuple(c.pop("terms", ("centre", "damping", "gyro", "spinup")))
    weight = c.pop("balance_weight_s", None)
    shell = RotationModel(layout, terms, (np.zeros(0),) * 3, np.zeros(3), int(c.pop("delay_steps", 0)),
                          float(rad_s_per_rpm), lowpass_tau_s=c.pop("lowpass_tau_s", None),
                          centre_tau_s=c.pop("centre_tau_s", None))
    if c:
        raise DataError(f"rotation_folds: unknown keyword(s) {', '.join(c)}")
    names = [log.name for log in logs]
    P = layout.patterns()
    M = layout.motors
    # per log: the prior's sums (Σ s in flight, rows) and the rows with s₀ (prior 0) and h
    sums, counts, rows, hs = np.zeros((len(logs), M)), np.zeros(len(logs)), [], []
    zero = shell if weight is None else dataclasses.replace(shell, balance_weight_s=float(weight), balance_prior=None)
    for i, log in enumerate(logs):
        if weight is not None:
            s_nb = shell.conditioned(log.rpm, log.dt_s)[0][flying_mask(log)]
            sums[i], counts[i] = s_nb.sum(axis=0), s_nb.shape[0]
            n = log.dt_s * np.arange(1, len(log) + 1)
            hs.append(float(weight) / (n + float(weight)))
        rows.append(rotation_rows(log, zero, window_s))
    if not any(r[0].any() for r in rows):
        raise DataError("fit_rotation: no training row with every motor turning in flight")
    groups = np.concatenate([np.full(int(r[0].sum()), j) for j, r in enumerate(rows)])
    prior_all = sums.sum(axis=0) / max(counts.sum(), 1.0)
    folds = {name: {"coef": [], "trims": np.zeros((sum(n != name for n in names), 3))}
             for name in dict.fromkeys(names) if any(n != name for n in names)}
    for k in range(3):
        base = [rotation_design(k, P, terms, r) for r in rows]
        nc = base[0].shape[1]
        # each motor's response column block: the design with s = h e_m, less the design without s
        resp = []
        for j, r in enumerate(rows):
            if weight is None:
                resp.append(np.zeros((base[j].shape[0], 0)))
                continue
            off = rotation_design(k, P, terms, r, np.zeros_like(r[1]))
            e = [rotation_design(k, P, terms, r, np.outer(hs[j][:-1], np.eye(M)[m])) - off for m in range(M)]
            resp.append(np.hstack(e))
        Z = np.vstack([np.hstack([b, q]) for b, q in zip(base, resp)])
        y = np.concatenate([r[4][r[0], k] for r in rows])
        lo = rotation_bounds(k, terms, nc)
        w = robust_fit_grouped(Z[:, :nc] - _prior_part(Z, nc, prior_all), y, groups, lo=lo).weights
        ids, S = group_grams(Z, y, w, groups)
        for name, fold in folds.items():
            train = np.array([names[g] != name for g in ids])
            prior = sums[[i for i in range(len(logs)) if names[i] != name]].sum(axis=0) / max(
                counts[[i for i in range(len(logs)) if names[i] != name]].sum(), 1.0)
            T = _fold_map(nc, Z.shape[1], prior if weight is not None else np.zeros(0))
            Sf = np.einsum("ai,gab,bj->gij", T, S[train], T)      # the fold's [A 1 y] statistics per log
            beta = gram_bounded_lstsq(within_gram(Sf), lo)
            fold["coef"].append(beta)
            at = np.flatnonzero([names[i] != name for i in range(len(logs))])
            fold["trims"][np.searchsorted(at, ids[train]), k] = group_intercepts(Sf, beta)
            fold["prior"] = prior
    out = {}
    for name, fold in folds.items():
        model = shell if weight is None else dataclasses.replace(shell, balance_weight_s=float(weight),
                                                                 balance_prior=fold["prior"])
        out[name] = dataclasses.replace(model, coef=tuple(fold["coef"]), trim=fold["trims"].mean(axis=0),
                                        flight_trims=fold["trims"])
    return out


def _prior_part(Z: np.ndarray, nc: int, prior: np.ndarray) -> np.ndarray:
    """Σ_m prior_m · (motor m's response block of ``Z``): what the prior takes off the s₀ design."""
    if Z.shape[1] == nc:
        return 0.0
    M = (Z.shape[1] - nc) // nc
    return sum(prior[m] * Z[:, nc * (1 + m):nc * (2 + m)] for m in range(M))


def _fold_map(nc: int, width: int, prior: np.ndarray) -> np.ndarray:
    """(width + 2, nc + 2): ``[Z 1 y] @ T = [Z_s₀ − Σ_m prior_m Z_m, 1, y]``, the fold's design from
    the statistics of ``[Z 1 y]`` (``T[:nc] = I``, motor m's block ``−prior_m I``)."""
    T = np.zeros((width + 2, nc + 2))
    T[:nc, :nc] = np.eye(nc)
    for m in range(prior.size):
        T[nc * (1 + m):nc * (2 + m), :nc] = -prior[m] * np.eye(nc)
    T[width, nc] = 1.0
    T[width + 1, nc + 1] = 1.0
    return T
