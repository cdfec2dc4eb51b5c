"""CLI subcommands, one module each, listed in :data:`COMMANDS` (read by :mod:`droneid.cli`).

A command module defines ``register(subparsers)``, which adds its parser (its ``description``
and options; the one-line help comes from :data:`COMMANDS`) and sets ``func=run`` via
``parser.set_defaults(func=run)``; ``run(args) -> int`` returns the exit code. Only the chosen
command's module is imported, so a module's top level and ``register`` import nothing heavy
(no engine, numba, sympy or pandas): ``droneid CMD --help`` stays instant, and ``run`` imports
what the command needs. Shared CLI helpers live in :mod:`droneid.commands._common`.

Adding a command: a module here plus one line in :data:`COMMANDS`.
"""
from __future__ import annotations

from typing import NamedTuple


class Command(NamedTuple):
    """A subcommand: the module that defines it (``register``/``run``), its one-line help (shown
    by ``droneid --help`` without importing the module) and whether the ``droneid`` process may
    end without the interpreter's teardown once it is done (``no_teardown``: the command leaves
    no worker running (its pools are joined), no temporary files, and closes what it writes)."""
    module: str
    help: str
    no_teardown: bool = False


#: every subcommand by name (``droneid --help`` lists them in this order)
COMMANDS: dict[str, Command] = {
    "dataset": Command("droneid.commands.dataset",
                       "export the regression table (inputs, target, t, flight) built from logs as CSV"),
    "demo": Command("droneid.commands.demo",
                    "identify v̇x, v̇y on the shipped sample logs (train eight, test square)"),
    "diagnose": Command("droneid.commands.diagnose",
                        "trace a prior model's residual to the physical effects it lacks"),
    "export": Command("droneid.commands.export",
                      "write the final models as self-contained Python, C, MATLAB or LaTeX"),
    "fit": Command("droneid.commands.fit",
                   "fit an analytic model to a CSV table with SNGP (priors, constraints)",
                   no_teardown=True),
    "identify": Command("droneid.commands.identify",
                        "identify models from logs and compare them with the empirical model",
                        no_teardown=True),
    "inspect": Command("droneid.commands.inspect",
                       "show the format, signals, rates, segments and diagnostics of a flight log"),
    "predict": Command("droneid.commands.predict",
                       "apply a saved model to other logs and report its error"),
    "sample-logs": Command("droneid.commands.sample_logs",
                           "regenerate the shipped sample logs (sample_logs/)"),
    "simulate": Command("droneid.commands.simulate",
                        "simulate a quadrotor flight and write .tlog/.mcap/Motive CSV + truth JSON"),
    "study": Command("droneid.commands.study",
                     "compare no/1/3 prior features, with and without constraints, over many runs"),
}
