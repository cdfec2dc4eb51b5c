"""Plug-in discovery: the public modules of a package, which is how the log readers
(:mod:`parsers`) and the built-in effects (:mod:`priors.effect_catalogue`) are found, so that
adding one is adding one module."""
from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterator
from types import ModuleType

__all__ = ["public_modules"]


def public_modules(package: str) -> Iterator[ModuleType]:
    """Import and yield every module of ``package`` whose name does not start with ``_``, in
    name order."""
    pkg = importlib.import_module(package)
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if not info.name.startswith("_"):
            yield importlib.import_module(f"{package}.{info.name}")
