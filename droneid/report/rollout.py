"""The multi-step prediction figures (error against horizon, traces) from the data of
:func:`droneid.simulation.rollout.horizon_section` (``RolloutResult.to_dict()``): velocities in m/s,
positions in m, horizons in s."""
from __future__ import annotations

import math
from collections.abc import Mapping

from droneid.simulation.rollout import AXES
from droneid.report.document import new_figure, png_bytes

__all__ = ["horizon_figures", "ONE_STEP_POSITION"]

#: why every model's 1-step position error is (nearly) the same, said where that column is shown
#: (identify's multi-step and open-loop tables, predict's)
ONE_STEP_POSITION = ("after 1 step a model that integrates moves the position by the logged start velocity (its "
                     "acceleration adds only ½·a·Δt²), so the 1-step position column measures the log "
                     "(a motion-capture position held between its updates), not the models")


def horizon_figures(section: Mapping) -> dict[str, bytes]:
    """PNG bytes of ``{"rollout_error_vs_horizon": ..., "rollout_traces": ...}`` from the data of
    :func:`horizon_section` (or ``RolloutResult.to_dict()``); the traces only when it holds some."""
    out = {}
    models = list(section["rmse"])
    keys = [k for k in ("vx", "vy", "vz", "position")
            if any(k in e for per in section["rmse"].values() for e in per.values())]
    fig = new_figure(3.0 * len(keys), 3.2)
    axs = fig.subplots(1, len(keys), squeeze=False)[0]
    secs = section["seconds"]
    for ax, k in zip(axs, keys):
        for m in models:
            y = [section["rmse"][m][str(h)].get(k, math.nan) for h in section["steps"]]
            if not all(v is None or v != v for v in y):
                ax.plot(secs, [math.nan if v is None else v for v in y], "o-", label=m)
        ax.set_xscale("log")
        ax.set_xlabel("horizon (s)")
        ax.set_ylabel("position RMSE (m)" if k == "position" else f"{k} RMSE (m/s)")
        ax.set_title(k)
        ax.grid(True, alpha=0.3)
    axs[0].legend(fontsize=7)
    out["rollout_error_vs_horizon"] = png_bytes(fig)
    segs = section.get("segments") or []
    if segs:
        axes_ = [a for a in AXES if a in segs[0]["measured"]]
        fig = new_figure(7.0, 1.9 * len(axes_) + 0.6)
        axs = fig.subplots(len(axes_), 1, squeeze=False, sharex=True)[:, 0]
        colors = {m: f"C{i}" for i, m in enumerate(models)}   # as in the error plot
        for ax, a in zip(axs, axes_):
            for si, s in enumerate(segs):   # one line per trace: gaps between traces are not bridged
                ax.plot(s["t"], s["measured"][a], color="k", lw=1.4, label="log" if si == 0 else None)
                for m in models:
                    if a in s["predicted"].get(m, {}):
                        ax.plot(s["t"], s["predicted"][m][a], color=colors[m], lw=1,
                                label=m if si == 0 else None)
            ax.set_ylabel(f"{a} (m/s)")
            ax.grid(True, alpha=0.3)
        axs[-1].set_xlabel("time from log start (s)")
        axs[0].legend(fontsize=7, ncol=len(models) + 1)
        out["rollout_traces"] = png_bytes(fig)
    return out
