"""The ``droneid`` command line. The only place in droneid that prints or exits.

Each subcommand lives in its own module under :mod:`droneid.commands` and exposes
``register(subparsers)``, which adds its parser and sets ``func=run`` (``run(args) -> int``).
Commands are discovered, so adding one never edits this file.
"""
from __future__ import annotations

import argparse
import importlib
import json
import logging
import os
import pkgutil
import sys

from . import __version__
from .errors import DroneIdError

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="droneid",
        description="Identify analytic models of drone dynamics from flight logs "
                    "(SNGP symbolic regression with prior features and formal constraints).",
    )
    parser.add_argument("--version", action="version", version=f"droneid {__version__}")
    _add_global_options(parser, default=False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    from . import commands
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    for command_parser in sub.choices.values():
        # `droneid fit ... -q` as well as `droneid -q fit ...`: SUPPRESS keeps the value given
        # before the command when the option is not repeated after it
        _add_global_options(command_parser, default=argparse.SUPPRESS)
    return parser


def _add_global_options(parser: argparse.ArgumentParser, default) -> None:
    """--debug and -q/--quiet, accepted before and after the command."""
    taken = parser._option_string_actions  # noqa: SLF001 - skip options a command defines itself
    if "--debug" not in taken:
        parser.add_argument("--debug", action="store_true", default=default,
                            help="show tracebacks and debug logging")
    if "-q" not in taken and "--quiet" not in taken:
        parser.add_argument("-q", "--quiet", action="store_true", default=default,
                            help="no progress output")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.debug else logging.WARNING,
        format="droneid: %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        return int(args.func(args) or 0)
    except DroneIdError as exc:
        if args.debug:
            raise
        print(f"droneid {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except UnicodeDecodeError as exc:  # a binary file (e.g. a log) given where text/JSON is read
        if args.debug:
            raise
        print(f"droneid {args.command}: error: {_text_file_hint(args, exc.object)}is not UTF-8 text "
              f"(byte 0x{exc.object[exc.start]:02x} at offset {exc.start}); check which file goes "
              f"where in `droneid {args.command} --help`", file=sys.stderr)
        return EXIT_USAGE
    except json.JSONDecodeError as exc:  # a non-JSON file given where JSON is read
        if args.debug:
            raise
        print(f"droneid {args.command}: error: {_text_file_hint(args, exc.doc.encode('utf-8', 'replace'))}"
              f"is not valid JSON ({exc.msg} at line {exc.lineno}); check which file goes where in "
              f"`droneid {args.command} --help`", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:  # e.g. `droneid inspect LOG | head`: the reader went away
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return EXIT_OK
    except OSError as exc:
        if args.debug:
            raise
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"droneid {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"droneid {args.command}: interrupted", file=sys.stderr)
        return 130


def _text_file_hint(args, content) -> str:
    """'FILE: ' for the file argument whose bytes begin as ``content`` (what failed to decode or
    parse), or a generic subject when no argument is that file."""
    head = bytes(content[:4096]) if isinstance(content, (bytes, bytearray)) else b""
    for value in vars(args).values():
        for v in value if isinstance(value, list) else [value]:
            if head and isinstance(v, str) and os.path.isfile(v):
                try:
                    with open(v, "rb") as fh:
                        if fh.read(len(head)) == head:
                            return f"{v}: "
                except OSError:
                    continue
    return "a file given as text "


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
