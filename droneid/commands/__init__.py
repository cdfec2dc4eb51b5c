"""CLI subcommands, one module each; discovered by :func:`droneid.cli.build_parser`.

A command module defines ``register(subparsers)`` which adds a parser and sets
``func=run`` via ``parser.set_defaults(func=run)``; ``run(args) -> int`` returns the exit code.
Shared CLI helpers live in :mod:`droneid.commands._common`.
"""
