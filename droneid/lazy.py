"""Modules loaded on first use, declared at the top of the module that uses them.

``identify = lazy_module("droneid.identify")`` binds a module object whose code runs the first
time an attribute is read (:class:`importlib.util.LazyLoader`, the mechanism of the scientific
Python ecosystem's SPEC 1 lazy loading). A command's module lists what it needs at its top, like
any import, yet ``droneid CMD --help`` does not pay for the engine, numba or sympy it only needs
to run. Its parent packages are imported at once, so name a module of a light package
(``droneid``, ``droneid.report``, ``priors``, ``parsers``): ``lazy_module("droneid.sngp")`` and
then ``.precompile``, not ``lazy_module("droneid.sngp.precompile")``.
"""
from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

__all__ = ["lazy_module"]


def lazy_module(name: str) -> ModuleType:
    """The module ``name`` (absolute), executed on first attribute access; the module itself
    when it is already imported."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    loader = importlib.util.LazyLoader(spec.loader)
    spec.loader = loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    loader.exec_module(module)
    parent, _, child = name.rpartition(".")
    if parent:
        setattr(sys.modules[parent], child, module)
    return module
