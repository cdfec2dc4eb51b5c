"""The reader registry: every module of the ``parsers`` package that exports ``READER`` (one
:class:`Reader`) or ``READERS`` (several) is a log format. Adding a format is one new module.

Discovery imports the package's public modules once, in sorted order, on first use (the reader
modules import their third-party libraries inside ``read``, so discovery stays cheap). Two
readers claiming one format name is a :class:`ConfigError` naming both modules.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType

from droneid.errors import ConfigError
from droneid.core.plugins import public_modules

__all__ = ["Reader", "discover", "clear_cache"]


@dataclass(frozen=True)
class Reader:
    """One log format.

    name : the format name (``--format NAME``).
    read : ``read(path, **options) -> Flight`` in the internal convention (ENU/FLU, SI, seconds).
    sniff : ``sniff(head) -> bool`` from the file's first 4096 bytes; content decides the
        format, the extension only names it in errors.
    order : sniffers run in increasing ``order`` (exact magic bytes ~10, heuristics later, the
        catch-all flat CSV last), ties by name.
    extensions : the usual file extensions, lower case with the dot (documentation and errors).
    options : the keyword options ``read`` accepts (e.g. ``("sysid",)``); any other option given
        to ``read_flight`` for this format is refused.
    description : one line for ``--help`` and the docs.
    """
    name: str
    read: Callable
    sniff: Callable[[bytes], bool]
    order: int = 50
    extensions: tuple[str, ...] = ()
    options: tuple[str, ...] = ()
    description: str = ""
    module: str = field(default="", compare=False)


_CACHE: dict[str, Reader] | None = None


def _module_readers(mod) -> list[Reader]:
    found = []
    if isinstance(getattr(mod, "READER", None), Reader):
        found.append(mod.READER)
    found.extend(r for r in getattr(mod, "READERS", ()) if isinstance(r, Reader))
    return found


def discover(package: str = "parsers") -> Mapping[str, Reader]:
    """Format name -> :class:`Reader`, from every public module of ``package`` (cached)."""
    global _CACHE
    if _CACHE is None:
        table: dict[str, Reader] = {}
        for mod in public_modules(package):
            for r in _module_readers(mod):
                here = getattr(mod, "__file__", mod.__name__)
                if r.name in table:
                    raise ConfigError(f"log format {r.name!r} is defined twice: in "
                                      f"{table[r.name].module} and in {here}")
                table[r.name] = replace(r, module=here)
        _CACHE = table
    return MappingProxyType(_CACHE)


def clear_cache() -> None:
    """Forget the discovered readers (tests that add a plug-in module call this)."""
    global _CACHE
    _CACHE = None
