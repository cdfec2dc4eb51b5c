"""The ``droneid`` command line. The only place in droneid that prints or exits.

The subcommands are listed in :data:`droneid.commands.COMMANDS` (name -> module, one-line help).
Only the chosen command's module is imported, once it has been chosen: ``droneid --help`` and
``droneid --version`` import no command module, and ``droneid CMD ...`` imports only CMD's
(which adds its parser with ``register(subparsers)`` and sets ``func=run``; ``run(args) -> int``).
"""
from __future__ import annotations

import argparse
import difflib
import importlib
import json
import logging
import os
import sys
from collections.abc import Iterable, Sequence

from droneid import __version__
from droneid.commands import COMMANDS
from droneid.errors import DroneIdError

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2


def build_parser(only: Iterable[str] | None = None) -> argparse.ArgumentParser:
    """The ``droneid`` parser. ``only``: the commands whose modules are imported and whose
    parsers are built (what :func:`main` passes: the chosen command); every other command is
    listed with its help only. None: every command is built (tests, documentation checks)."""
    parser = argparse.ArgumentParser(
        prog="droneid", allow_abbrev=False,
        description="Identify analytic models of drone dynamics from flight logs "
                    "(SNGP symbolic regression with prior features and formal constraints).",
    )
    parser.add_argument("--version", action="version", version=f"droneid {__version__}")
    _add_global_options(parser, default=False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    wanted = None if only is None else set(only)
    for name, command in COMMANDS.items():
        if wanted is None or name in wanted:
            importlib.import_module(command.module).register(_Subcommands(sub))
        else:
            sub.add_parser(name, help=command.help, add_help=False)
    for command_parser in sub.choices.values():
        # `droneid fit ... -q` as well as `droneid -q fit ...`: SUPPRESS keeps the value given
        # before the command when the option is not repeated after it
        _add_global_options(command_parser, default=argparse.SUPPRESS)
    return parser


class _Subcommands:
    """The subparsers action as a command module's ``register`` sees it: ``add_parser`` takes
    the command's one-line help from :data:`COMMANDS` (its one home)."""

    def __init__(self, action):
        self._action = action

    def add_parser(self, name: str, **kwargs) -> argparse.ArgumentParser:
        kwargs["help"] = COMMANDS[name].help
        # an abbreviation is a guess: --horizon was read as --horizons; the refusal names the option
        kwargs.setdefault("allow_abbrev", False)
        return self._action.add_parser(name, **kwargs)


def chosen_command(argv: Sequence[str]) -> str | None:
    """The command named in ``argv``: the first argument that is not an option (the options
    before a command take no values), or None (no command, or an unknown one)."""
    for arg in argv:
        if arg == "--":
            break
        if not arg.startswith("-"):
            return arg if arg in COMMANDS else None
    return None


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
    """Run the command in ``argv`` (None: this process's own arguments) and return its exit code.

    As the process itself (``argv`` None), a command marked ``no_teardown`` in the registry ends
    the process here once it is done, without the interpreter's teardown (freeing every object of
    sympy, numba and pandas: 0.1-0.3 s that the user would wait for)."""
    process = argv is None
    argv = sys.argv[1:] if argv is None else list(argv)
    command = chosen_command(argv)
    parser = build_parser(only=() if command is None else (command,))
    args, extra = parser.parse_known_args(argv)
    if extra:
        _refuse_unknown(parser, command, extra)
    logging.basicConfig(
        level=logging.DEBUG if args.debug else logging.WARNING,
        format="droneid: %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    code = _run(args)
    if process and COMMANDS[args.command].no_teardown:
        _end_process(code)
    return code


def _refuse_unknown(parser: argparse.ArgumentParser, command: str | None, extra: Sequence[str]) -> None:
    """argparse's "unrecognized arguments" (exit 2), from the command's own parser (its usage
    line), with the nearest option named for an option that is a typo ("--quik": did you mean
    --quick?)."""
    sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)  # noqa: SLF001
    own = sub.choices[command] if sub is not None and command in sub.choices else parser
    known = [o for o in own._option_string_actions if o.startswith("--")]  # noqa: SLF001
    hints = []
    for arg in extra:
        if arg.startswith("--"):
            near = difflib.get_close_matches(arg.split("=", 1)[0], known, n=1, cutoff=0.6)
            if near:
                hints.append(f"{arg}: did you mean {near[0]}?")
    if len(extra) == 1 and hints:
        hints = [hints[0].split(": ", 1)[1]]
    own.error(f"unrecognized arguments: {' '.join(extra)}" + (f" ({'; '.join(hints)})" if hints else ""))


def _end_process(code: int) -> None:
    """End the process now: flush what was written and exit without the interpreter's teardown
    (for commands that leave nothing to clean up: no workers, no temporary files, files closed)."""
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):   # a closed pipe: nothing more can be written anyway
            pass
    os._exit(code)


def _run(args: argparse.Namespace) -> int:
    """The command's ``run``, with droneid's errors mapped to one line on stderr and exit 2."""
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
