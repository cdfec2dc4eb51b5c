"""What the final models predict on other flights, as arrays: v̇ per target on the flight's time
grid and, with horizons, the states they simulate (``IdentificationResult.predict``).

The rows of a target are the rows ``droneid predict`` scores (:func:`droneid.use.predict.final_predictions`:
the in-flight grid at the sampling period the model was identified with, inputs read at their
delays, screened samples left out), so ``Score`` is the RMSE of ``final - measured`` on them.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

from droneid.errors import ConfigError, check_choice
from droneid.use.predict import final_predictions, flight_list, model_sets
from droneid.simulation.rollout import rollout_errors

__all__ = ["TargetPrediction", "PredictionResult", "predict_models"]

#: the models a target's prediction holds, in column order
MODELS = ("final", "empirical", "refit")
_KEYS = {"final": "identified", "empirical": "empirical", "refit": "refit"}


@dataclass(frozen=True)
class TargetPrediction:
    """One target on the flights' grid (``unit``: m/s² for v̇). Arrays of one length, one row per
    grid sample: ``t_s`` time (s from the start of its log), ``flight`` the log's name, ``measured``
    the target taken from the log (the differentiator identify used), ``final`` the final model's
    prediction, ``empirical`` the empirical model's as given and ``refit`` the prior's refit
    (None where the result holds no such model)."""
    target: str
    unit: str
    t_s: np.ndarray
    flight: np.ndarray
    measured: np.ndarray
    final: np.ndarray
    empirical: np.ndarray | None = None
    refit: np.ndarray | None = None

    def __repr__(self) -> str:
        span = f"{self.t_s.min():.3g}..{self.t_s.max():.3g} s" if self.t_s.size else "no rows"
        return f"TargetPrediction({self.target!r}, {self.t_s.size} rows, {span}, unit={self.unit!r})"

    def to_frame(self) -> pd.DataFrame:
        """Columns ``flight``, ``t_s`` (s), ``measured``, ``final``, ``empirical``, ``refit`` (in ``unit``)."""
        import pandas as pd     # at the edge only: identify's import path does without it (0.5 s)
        cols = {"flight": self.flight, "t_s": self.t_s, "measured": self.measured}
        cols.update({m: getattr(self, m) for m in MODELS if getattr(self, m) is not None})
        return pd.DataFrame(cols)


@dataclass(frozen=True)
class PredictionResult:
    """The final models' predictions on flights.

    ts : sampling period of the grid (s) and method : differentiator of ``measured`` (as identified
    with); sources : the flights' names; targets : {target: :class:`TargetPrediction`};
    horizons : the steps simulated (empty without horizons) and dt_s their step (s, the log's rate);
    states : {steps: {column: array}} the final models' simulated states ``steps`` after every
    valid start: ``flight``, ``t0_s`` (start, s), ``t_s`` (s), world velocities ``vx``, ``vy``,
    ``vz`` (m/s) of the modelled axes and positions ``x``, ``y``, ``z`` (m, where logged), and
    each as logged (``vx_logged``, …) at ``t_s`` (velocities integrated by RK4 from the logged
    start, every other signal from the log: :mod:`droneid.simulation.rollout`).
    """
    ts: float
    method: str
    sources: tuple[str, ...]
    targets: Mapping[str, TargetPrediction]
    horizons: tuple[int, ...] = ()
    dt_s: float | None = None
    states: Mapping[int, Mapping[str, np.ndarray]] = field(default_factory=dict, repr=False)

    def __repr__(self) -> str:
        lines = [f"PredictionResult(ts={self.ts:g} s, method={self.method!r}, flights={list(self.sources)})"]
        lines += [f"  {t.target}: {t.t_s.size} rows ({t.unit})" for t in self.targets.values()]
        if self.horizons:
            lines.append(f"  states at {list(self.horizons)} steps of {self.dt_s:g} s")
        return "\n".join(lines)

    def to_frame(self, target: str | None = None) -> pd.DataFrame:
        """One target's predictions (:meth:`TargetPrediction.to_frame`), or with ``target=None``
        every target's, stacked, with a ``target`` column."""
        if target is not None:
            check_choice("target", target, list(self.targets))
            return self.targets[target].to_frame()
        import pandas as pd
        frames = [p.to_frame().assign(target=t) for t, p in self.targets.items()]
        return pd.concat(frames, ignore_index=True)[["target", *frames[0].columns.drop("target")]]

    def states_frame(self, steps: int) -> pd.DataFrame:
        """The simulated states ``steps`` ahead (see ``states``) as a DataFrame."""
        import pandas as pd
        check_choice("steps", steps, list(self.states))
        return pd.DataFrame(dict(self.states[steps]))


def predict_models(models: dict, flights: Sequence, *, horizons: Sequence[int] | None = None,
                   ts: float | None = None, method: str | None = None) -> PredictionResult:
    """:class:`PredictionResult` of the models of :func:`droneid.use.predict.load_models` (or
    ``models_from_document``) on ``flights`` (a Flight or a sequence); ``horizons`` (steps at the log's rate) adds the
    simulated states; ``ts`` (s) and ``method`` default to the ones identified with."""
    flights = flight_list(flights)
    ts, method, _, predicted = final_predictions(models, flights, ts, method)
    targets = {}
    for target, (ds, preds, _) in predicted.items():
        unit = models[target]["identified"].unit if "identified" in models[target] else "m/s^2"
        names = np.asarray(ds.sources, dtype=object)[ds.flight] if ds.sources else np.empty(0, object)
        targets[target] = TargetPrediction(target, unit, ds.t, names, ds.y,
                                           *(preds.get(_KEYS[m]) for m in MODELS))
    if not horizons:
        return PredictionResult(ts, method, tuple(f.name for f in flights), targets)
    sets = model_sets(models)
    if "identified" not in sets:
        raise ConfigError("simulated states (horizons) need the final models of vx_dot / vy_dot / vz_dot")
    roll = rollout_errors({"identified": sets["identified"]}, flights, horizons, keep_states="identified")
    return PredictionResult(ts, method, tuple(f.name for f in flights), targets, roll.horizons, roll.dt_s,
                            dict(roll.states or {}))
