"""Modules loaded on first use, declared at the top of the module that uses them.

``identify = lazy_module("droneid.identify.pipeline")`` binds a stand-in whose first attribute read
imports the module (``importlib.import_module``, under the import system's own per-module lock,
so threads that reach it together get the same, fully executed module). A command's module
lists what it needs at its top, like any import, yet ``droneid CMD --help`` does not pay for the
engine, numba or sympy it only needs to run. Nothing is imported, not even parent packages,
until then. (``importlib.util.LazyLoader`` does the same on Python 3.12+, but on 3.11 a second
thread can see a half-executed module.)
"""
from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["lazy_module", "LazyModule"]


class LazyModule:
    """A module by name, imported at the first attribute read; ``loaded`` says whether it was."""

    __slots__ = ("_name", "_module")

    def __init__(self, name: str):
        self._name = name
        self._module: ModuleType | None = None

    @property
    def loaded(self) -> bool:
        return self._module is not None

    def __getattr__(self, attr: str):
        module = self._module
        if module is None:
            module = importlib.import_module(self._name)
            self._module = module
        return getattr(module, attr)

    def __repr__(self) -> str:
        return f"<lazy module {self._name!r}{'' if self.loaded else ' (not loaded)'}>"


def lazy_module(name: str) -> LazyModule:
    """The module ``name`` (absolute), imported on first attribute access."""
    return LazyModule(name)
