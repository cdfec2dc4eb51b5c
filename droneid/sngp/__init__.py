"""SNGP symbolic regression with prior features and formal constraints (the paper's engine).

``SNGPRegressor`` is the estimator; ``SymbolicModel`` a fitted equation that can be saved as
JSON (``to_dict``/``from_dict``) and evaluated with numpy. The operator table is in
:mod:`droneid.sngp.operators`, the compiled kernels in :mod:`droneid.sngp.kernels`.
:func:`warmup` compiles the kernels ahead (an install step; a parallel runner before it starts
workers); :func:`kernels_ready` says whether the next fit would compile them first.
"""
from droneid.sngp.estimator import SNGPRegressor
from droneid.sngp.operators import DEFAULT_FUNCTIONS, OPERATORS
from droneid.sngp.precompile import kernels_ready, warmup
from droneid.core.lazy import lazy_module

_model = lazy_module("droneid.sngp.model")

__all__ = ["SNGPRegressor", "SymbolicModel", "DEFAULT_FUNCTIONS", "OPERATORS", "kernels_ready",
           "warmup"]


def __getattr__(name: str):
    # SymbolicModel (sympy) on first use: the search runs before sympy is imported
    if name == "SymbolicModel":
        return _model.SymbolicModel
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
