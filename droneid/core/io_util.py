"""Atomic output: every file droneid writes appears whole or not at all."""
from __future__ import annotations

import errno
import json
import math
import os
import tempfile
from pathlib import Path

from droneid.errors import ConfigError


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same folder and ``os.replace``.

    An ``OSError`` names ``path`` (never the temporary file): e.g. ``IsADirectoryError`` when
    ``path`` is a folder.
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder; give a file name", str(path))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise _naming(exc, path) from None
    try:
        os.chmod(tmp, 0o666 & ~current_umask())  # mkstemp makes 0600; give the usual permissions
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise _naming(exc, path) from None
        raise
    return path


def _naming(exc: OSError, path: Path) -> OSError:
    """The same kind of OSError, naming ``path`` instead of a temporary file."""
    return type(exc)(exc.errno, exc.strerror or str(exc), str(path))


def current_umask() -> int:
    """The process's file-creation mask (read without changing it for longer than a call)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def to_jsonable(obj):
    """Convert numpy scalars/arrays and non-finite floats (-> None) for strict JSON."""
    import numpy as np
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def json_text(obj, indent: int = 2) -> str:
    """``obj`` as strict JSON text (numpy converted, non-finite floats as null), newline-ended."""
    return json.dumps(to_jsonable(obj), indent=indent, allow_nan=False) + "\n"


def atomic_write_json(path, obj, indent: int = 2) -> Path:
    return atomic_write_text(path, json_text(obj, indent))


def load_toml(path, what: str = "file") -> dict:
    """Parse the TOML file at ``path``; a syntax error or an unreadable file raises
    :class:`droneid.errors.ConfigError` naming the file (``what`` says what it should hold)."""
    import tomllib
    p = Path(path)
    try:
        return tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{p}: not valid TOML: not UTF-8 text") from None
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read {what}: {exc.strerror or exc}") from None
