"""The one exception family of droneid.

Every error droneid raises on purpose derives from :class:`DroneIdError` and also from the
builtin that fits (``ValueError``, ``KeyError``, ``OSError``), so callers can catch either.
The CLI maps the whole family to exit code 2 and one line on stderr.
"""
from __future__ import annotations

import difflib
from collections.abc import Iterable


def printable(text: str) -> str:
    """``text`` with every non-printable character (control characters, line breaks, format
    characters) escaped as Python does (``\\x07``, ``\\n``, ``\\u200b``): an error message that
    quotes bytes taken from a file stays one readable line."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


class DroneIdError(Exception):
    """Base class of every error droneid raises on purpose. Its text is :func:`printable`."""

    def __str__(self) -> str:
        return printable(super().__str__())


class LogFormatError(DroneIdError, ValueError):
    """A log file cannot be read: unknown format, empty, corrupt beyond use."""

    def __init__(self, path, problem: str):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class MissingSignalError(DroneIdError, KeyError):
    """A signal a stage needs is not in the flight or table."""

    def __init__(self, name: str, available: Iterable[str] = (), where: str = ""):
        self.name = name
        self.available = sorted(available)
        msg = f"signal '{name}' is not available"
        if where:
            msg += f" in {where}"
        msg += did_you_mean(name, self.available)
        if self.available and not did_you_mean(name, self.available):
            shown = ", ".join(self.available[:12]) + (", ..." if len(self.available) > 12 else "")
            msg += f" (available: {shown})"
        self.message = msg
        super().__init__(msg)

    def __str__(self) -> str:  # KeyError would quote the message
        return printable(self.message)


class ConfigError(DroneIdError, ValueError):
    """A parameter, option, prior, constraint or config file is invalid."""


class NotFittedError(DroneIdError, AttributeError):
    """An estimator was used before ``fit``."""


class DataError(DroneIdError, ValueError):
    """The data are unusable for the requested stage (too few samples, non-finite values, ...)."""


class ConventionError(DataError):
    """Flights whose redundant signals disagree the way a convention mistake makes them disagree
    (:mod:`droneid.logs.consistency`): a head line, then one line per finding naming the file and the
    reader option that fixes it (the one error whose text has several lines)."""

    def __init__(self, lines: Iterable[str], role: str = ""):
        self.lines = tuple(lines)
        what = f"the {role} data" if role else "the data"
        self.head = (f"{what} look read in the wrong convention ({len(self.lines)} finding(s)); refused "
                     f"before any fit, rerun with the fix:")
        super().__init__(self.head, *self.lines)

    def __str__(self) -> str:
        # one printable line each: the head, then one line per finding naming its file
        return "\n".join(printable(x) for x in (self.head, *self.lines))


def did_you_mean(name: str, choices: Iterable[str]) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest valid name, or ``""``."""
    close = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def check_choice(param: str, value, choices: Iterable, owner: str = "") -> None:
    """Raise ConfigError in the scikit-learn style when ``value`` is not one of ``choices``."""
    choices = list(choices)
    if value not in choices:
        where = f" of {owner}" if owner else ""
        hint = did_you_mean(str(value), [str(c) for c in choices])
        raise ConfigError(
            f"The '{param}' parameter{where} must be one of {choices}. Got {value!r} instead.{hint}"
        )
