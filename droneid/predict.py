"""Apply saved identified models to other logs and measure their error.

Accepts either an identification result (``result.json`` of ``droneid identify``: every target's
best model, plus its empirical baselines for comparison) or a bare model file (the engine's
``to_dict()``, with its target named by the caller). The data are built with the same sampling
period and differentiator the model was identified with.
"""
from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .errors import ConfigError, DataError, check_choice
from .numerics import rmse

__all__ = ["load_models", "predict_flights"]


def load_models(path, targets: Sequence[str] | None = None) -> dict:
    """{target: {"model", "inputs", "empirical_refit", ...}} plus "_config" from a JSON file."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise DataError(f"{path}: not a JSON file ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(doc, dict):
        raise DataError(f"{path}: expected a JSON object (an identify result.json or a model file)")
    if "targets" in doc:
        available = [t for t, tr in doc["targets"].items() if tr.get("model")]
        if not available:
            raise DataError(f"{path}: the result holds no finished model")
        chosen = list(targets) if targets else available
        for t in chosen:
            check_choice("target", t, available, owner=str(path))
        out = {t: {"model": doc["targets"][t]["model"], "inputs": doc["targets"][t]["inputs"],
                   "empirical_terms": doc["targets"][t].get("empirical_terms") or [],
                   "empirical_refit": doc["targets"][t].get("empirical_refit") or {},
                   "empirical_expr": (doc["targets"][t].get("empirical") or {}).get("expr"),
                   "equation": doc["targets"][t].get("equation")} for t in chosen}
        out["_config"] = doc.get("config") or {}
        return out
    # a bare model file (SNGPRegressor.to_dict()): its target is saved in it or named by the caller
    from .identify import TARGETS
    target = targets[0] if targets and len(targets) == 1 else doc.get("target")
    if target not in TARGETS:
        raise ConfigError(f"{path} is a single model without a known target: name it with --target "
                          f"(one of {', '.join(TARGETS)})")
    inputs = doc.get("inputs")
    if not inputs:
        raise DataError(f"{path}: a model file must list its 'inputs'")
    return {target: {"model": doc, "inputs": list(inputs), "empirical_terms": [],
                         "empirical_refit": {}, "equation": doc.get("equation")}, "_config": {}}




def predict_flights(models: dict, flights: Sequence, *, ts: float | None = None,
                    method: str | None = None) -> dict:
    """Per target and per flight (and all together): samples, rmse of the identified model and,
    when the result holds them, of the empirical model as given and as refit."""
    from droneid.dataset import DatasetBuilder
    from droneid.sngp import SymbolicModel

    from .expressions import compile_expression, parse_expression
    cfg = models.get("_config", {})
    ts = ts or cfg.get("ts") or 0.05
    method = method or cfg.get("method") or "forward"
    builder = DatasetBuilder(ts=ts, method=method)
    out = {"ts": ts, "method": method, "targets": {}}
    for target, m in models.items():
        if target.startswith("_"):
            continue
        model = SymbolicModel.from_dict(m["model"])
        ds = builder.build(list(flights), target=target, inputs=tuple(m["inputs"]))
        cols = ds.columns()
        pred = np.asarray(model.predict(cols), float)
        preds = {"identified": pred}
        terms, refit = m.get("empirical_terms") or [], m.get("empirical_refit") or {}
        ev = lambda text: compile_expression(parse_expression(text, ds.input_names, what="empirical model"),  # noqa: E731
                                             ds.input_names)(cols)
        if m.get("empirical_expr"):
            preds["empirical"] = ev(m["empirical_expr"])
        if terms and refit.get("coefficients"):
            vals = [ev(tm["expr"]) for tm in terms]
            coefs = refit["coefficients"]
            preds["empirical_refit"] = (sum(coefs.get(tm["name"], 0.0) * v for tm, v in zip(terms, vals))
                                        + float(refit.get("intercept") or 0.0))
        per = {}
        groups = [("all", np.ones(len(ds), bool))]
        if len(ds.sources) > 1:
            groups += [(src, ds.flight == i) for i, src in enumerate(ds.sources)]
        for name, mask in groups:
            per[name] = {"n": int(mask.sum()), **{f"rmse_{k}": rmse(v[mask], ds.y[mask]) for k, v in preds.items()}}
        out["targets"][target] = {"equation": m.get("equation"), "inputs": list(ds.input_names),
                                  "sources": list(ds.sources), "errors": per}
    return out
