"""droneid: identify analytic models of drone dynamics from flight logs.

The Python API (docs/api.md), imported on first use so that ``droneid --version`` stays fast:

- ``droneid.read_log(path, **options) -> Flight``;
- ``droneid.Identifier(prior=…, differentiator=…, constraints=…, effects=…).fit(flights)`` ->
  :class:`droneid.identify.result.IdentificationResult`, with ``.predict(flight)`` (a
  :class:`PredictionResult`: v̇ on the flight's grid), ``.score(flight)`` (a :class:`Score`: the
  error tables) and ``.export(lang)``.

Stages (one object, one verb each): ``parsers.read_flight(path) -> Flight``, dataset building
``Flight -> Dataset``, the plan, the problem, the SNGP search, the ladder, and reports. See
docs/signals.md for the frame and unit conventions.
"""
import os as _os

# droneid's linear algebra is least squares on thousands of rows by a few columns, and its parallel
# work runs in forked processes: one BLAS thread each is fastest. A threaded BLAS made the same
# small solves 2x slower idle and 20x slower on a loaded 2-core machine (docs/benchmarks.md), with
# bit for bit the same results. Set before numpy loads; a value the user set is kept, and numpy
# imported before droneid keeps its own threads.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
del _var

# library code never prints: droneid's log records reach a user only through a handler the
# application configures (the command line does, droneid/cli.py), not Python's last-resort stderr
import logging as _logging

_logging.getLogger(__name__).addHandler(_logging.NullHandler())
del _logging

__version__ = "0.1.0"

__all__ = ["__version__", "read_log", "Identifier", "IdentificationResult", "PredictionResult", "Score"]

_API = {"read_log": "droneid.api", "Identifier": "droneid.api", "IdentificationResult": "droneid.identify.result",
        "PredictionResult": "droneid.use.prediction", "Score": "droneid.use.score"}


def __getattr__(name):
    if name in _API:
        import importlib
        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'droneid' has no attribute {name!r}")
