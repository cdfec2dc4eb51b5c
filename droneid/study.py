"""The paper's multi-run comparison on the user's data (its Tables II-III).

Scenarios baseline (unconstrained) and constrained × prior variants none / 1 / 3 features ×
R runs per target. Every run of every variant is an independent job, so the whole study goes
through one :func:`droneid.runner.run_jobs` batch (local pool or Dask). Per variant the study
reports the median e_d^test and e_c^test over runs, and a Wilcoxon rank-sum p-value
(``scipy.stats.ranksums``) of each prior variant's test errors against the no-prior variant of
the same scenario. The result is plain data; :func:`study_document` / :func:`format_study` render it.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from .errors import DataError
from .identify import (IdentifyConfig, make_jobs, prepare_target, run_job, select_best, versions,
                       flight_provenance)
from .reporting import Document, new_figure

__all__ = ["study", "SCENARIOS", "PRIOR_VARIANTS", "study_table", "format_study", "study_document",
           "write_study"]

SCENARIOS = (("baseline", False), ("constrained", True))
PRIOR_VARIANTS = (0, 1, 3)
STUDY_SCHEMA = "droneid.study/1"


def _variant(scenario: str, nprior: int) -> str:
    return f"{scenario}/{nprior}"


def _label(nprior: int) -> str:
    return "no prior" if nprior == 0 else f"{nprior} prior feature" + ("" if nprior == 1 else "s")


def _ranksum_p(a, b) -> float:
    from scipy.stats import ranksums
    a = np.asarray([v for v in a if v is not None and math.isfinite(v)], float)
    b = np.asarray([v for v in b if v is not None and math.isfinite(v)], float)
    if a.size < 2 or b.size < 2:
        return float("nan")
    return float(ranksums(a, b).pvalue)


def _median(vals) -> float:
    v = np.asarray([x for x in vals if x is not None and math.isfinite(x)], float)
    return float(np.median(v)) if v.size else float("nan")


def study(train_flights: Sequence, test_flights: Sequence | None, config: IdentifyConfig,
          progress: Callable | None = None) -> dict:
    """Run the study; ``config.runs`` runs per (target, scenario, prior variant)."""
    from .runner import run_jobs
    cfg = config.validated()
    if cfg.constraints == "none":
        cfg = replace(cfg, constraints="paper")
    # the study reports errors only: skip the per-run sympy simplification (a third of a run)
    cfg = replace(cfg, simplify_s=0.0)
    # the paper's protocol: its prior, constraints and data as given (no thrust delay, no folded
    # effects, no drag-sign constraints), whatever identify's defaults are
    cfg = replace(cfg, effects="none", delays="none", prior="tilt-drag" if cfg.prior == "auto" else cfg.prior)
    t0 = time.perf_counter()
    problems = {t: prepare_target(train_flights, test_flights, t, cfg) for t in cfg.targets}
    jobs = []
    for t in cfg.targets:
        for scenario, constrained in SCENARIOS:
            for k in PRIOR_VARIANTS:
                jobs += make_jobs(problems[t], cfg, prior_features=k, constrained=constrained,
                                  variant=_variant(scenario, k))
    # the paper's protocol: every run spends the whole budget (no early stopping)
    jobs = [replace(j, engine={**j.engine, "early_stop_window": None}) for j in jobs]
    outcome = run_jobs(run_job, jobs, n_jobs=cfg.jobs, scheduler=cfg.scheduler, progress=progress,
                       label="SNGP run")
    keep = ("seed", "rmse_train", "rmse_test", "constraint_rmse_train", "constraint_rmse_test",
            "qualified", "wall_s", "equation")
    targets = {}
    for t in cfg.targets:
        p = problems[t]
        variants = {}
        for scenario, _ in SCENARIOS:
            for k in PRIOR_VARIANTS:
                v = _variant(scenario, k)
                idx = [i for i, j in enumerate(jobs) if j.target == t and j.variant == v]
                runs = [outcome.results[i] for i in idx if outcome.results[i] is not None]
                best = select_best(runs)
                variants[v] = {
                    "scenario": scenario, "prior_features": k, "n_runs": len(runs),
                    "failed": [outcome.errors[i] for i in idx if i in outcome.errors],
                    "median_rmse_train": _median(r["rmse_train"] for r in runs),
                    "median_rmse_test": _median(r["rmse_test"] for r in runs),
                    "median_constraint_rmse_test": _median(r["constraint_rmse_test"] for r in runs),
                    "best_equation": runs[best]["equation"] if best is not None else None,
                    "runs": [{key: r.get(key) for key in keep} for r in runs]}
        for scenario, _ in SCENARIOS:
            ref = [r["rmse_test"] for r in variants[_variant(scenario, 0)]["runs"]]
            for k in PRIOR_VARIANTS:
                v = variants[_variant(scenario, k)]
                v["p_value_vs_no_prior"] = (None if k == 0 else
                                            _ranksum_p([r["rmse_test"] for r in v["runs"]], ref))
        targets[t] = {"n_train": len(p.train), "n_test": len(p.test), "test_data": p.test_description,
                      "notes": list(p.notes),
                      "empirical": dict(p.empirical),
                      "empirical_refit": {k: v for k, v in p.empirical_refit.items()},
                      "variants": variants}
    if not outcome.n_done and not outcome.interrupted:
        raise DataError("every SNGP run of the study failed; first error: "
                        + next(iter(outcome.errors.values()), "unknown"))
    from .io_util import to_jsonable
    return to_jsonable({"schema": STUDY_SCHEMA, "targets": targets, "config": cfg.to_dict(),
            "provenance": {"train": flight_provenance(train_flights),
                           "test": flight_provenance(test_flights or [])},
            "versions": versions(), "interrupted": outcome.interrupted, "backend": outcome.backend,
            "runs_total": len(jobs), "runs_finished": outcome.n_done,
            "wall_s": time.perf_counter() - t0})


# ------------------------------------------------------------------------------------------------
# rendering (pure)


def _p(v) -> str:
    if v is None:
        return "—"
    v = float(v)
    if not math.isfinite(v):
        return "—"
    return f"{v:.2g}" if v >= 1e-3 else f"{v:.1e}"


def efmt(v) -> str:
    from .report_identify import efmt as _efmt
    return _efmt(v)


def _direction(median, median_none, nprior: int) -> str:
    """' (lower)' / ' (higher)': the variant's median test error against no prior's (the
    rank-sum test is two-sided, so the p-value alone does not say which way)."""
    if nprior == 0 or median is None or median_none is None:
        return ""
    return " (lower)" if median < median_none else " (higher)" if median > median_none else ""


def study_table(result: dict) -> tuple[list[str], list[list[str]]]:
    """Header and rows shaped like the paper's Tables II-III: one row per scenario × prior
    variant, per target the median e_d^test, the median e_c^test and the two-sided rank-sum p-value of
    the test errors against the same scenario's no-prior variant, with the direction of the
    difference in medians."""
    names = list(result["targets"])
    header = ["scenario", "prior"]
    for t in names:
        header += [f"{t} e_d test", f"{t} e_c test", f"{t} p vs none"]
    rows = []
    for scenario, _ in SCENARIOS:
        for k in PRIOR_VARIANTS:
            row = [scenario, _label(k)]
            for t in names:
                v = result["targets"][t]["variants"][_variant(scenario, k)]
                none = result["targets"][t]["variants"][_variant(scenario, 0)]["median_rmse_test"]
                row += [efmt(v["median_rmse_test"]), efmt(v["median_constraint_rmse_test"]),
                        _p(v["p_value_vs_no_prior"]) + _direction(v["median_rmse_test"], none, k)]
            rows.append(row)
    for key, label in (("empirical", "as given"), ("empirical_refit", "refit (LS)")):
        row = ["empirical model", label]
        for t in names:
            e = result["targets"][t][key]
            row += [efmt(e["rmse_test"]), efmt(e["constraint_rmse_test"]), "—"]
        rows.append(row)
    return header, rows


def format_study(result: dict) -> str:
    from .report_identify import _text_table
    cfg = result["config"]
    head = (f"droneid study: {cfg['runs']} run(s) per variant, {cfg['generations']} generations x population "
            f"{cfg['population_size']}; medians over runs, errors in m/s²; p = Wilcoxon rank-sum test of the "
            f"test errors against the same scenario's no-prior variant.")
    lines = [head]
    for t, tr in result["targets"].items():
        lines.append(f"{t}: {tr['n_train']} training / {tr['n_test']} test samples; {tr['test_data']}")
        lines += [f"  NOTE: {n}" for n in tr.get("notes") or []]
    if result.get("interrupted"):
        lines.append(f"NOTE: interrupted; {result['runs_finished']} of {result['runs_total']} runs finished")
    header, rows = study_table(result)
    lines += ["", _text_table(header, rows), "", f"wall time {result['wall_s']:.1f} s ({result['backend']})"]
    return "\n".join(lines)


def fig_study_box(t: str, tr: dict):
    """Box plot of the test errors (m/s²) per scenario and prior variant of one target; the tick
    labels name the scenario and the prior variant in full."""
    fig = new_figure(7.5, 3.8)
    ax = fig.add_subplot()
    data, labels = [], []
    for v in tr["variants"].values():
        vals = [r["rmse_test"] for r in v["runs"] if r["rmse_test"] is not None]
        data.append(vals if vals else [float("nan")])
        labels.append(f"{v['scenario']}\n{_label(v['prior_features'])}")
    ax.boxplot(data, tick_labels=labels)
    ax.tick_params(axis="x", labelsize=8)
    ax.set_xlabel("scenario and prior variant")
    ax.axhline(tr["empirical"]["rmse_test"], color="tab:orange", ls="--", label="empirical model")
    ax.set_ylabel("e_d test (m/s²)")
    finite = [x for d in data for x in d if x == x]
    if finite and max(finite) / max(min(finite), 1e-12) > 30:
        ax.set_yscale("log")
    ax.legend(fontsize=8)
    ax.set_title(f"{t}: test error per variant")
    return fig


def study_document(result: dict) -> Document:
    cfg = result["config"]
    doc = Document("droneid study: prior features and constraints")
    doc.paragraph(f"{cfg['runs']} SNGP run(s) per (target, scenario, prior variant), {cfg['generations']} "
                  f"generations, population {cfg['population_size']}, seed {cfg['seed']}; prior '{cfg['prior']}', "
                  f"constraints '{cfg['constraints']}' in the constrained scenario. Medians over runs; errors "
                  f"in m/s²; p = Wilcoxon rank-sum test (scipy.stats.ranksums) of each prior variant's test "
                  f"errors against the no-prior variant of the same scenario.")
    if result.get("interrupted"):
        doc.paragraph(f"NOTE: interrupted; {result['runs_finished']} of {result['runs_total']} runs finished.")
    header, rows = study_table(result)
    doc.table(header, rows)
    for t, tr in result["targets"].items():
        doc.heading(t)
        doc.paragraph(f"{tr['n_train']} training / {tr['n_test']} test samples; {tr['test_data']}.")
        for n in tr.get("notes") or []:
            doc.paragraph(f"NOTE: {n}")
        fig = fig_study_box(t, tr)
        doc.figure(fig, f"study_{t}", "test errors per scenario and prior variant")
    return doc


def write_study(result: dict, directory) -> None:
    study_document(result).write(directory, "study", data={"study.json": result})
