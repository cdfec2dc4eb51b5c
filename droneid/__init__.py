"""droneid: identify analytic models of drone dynamics from flight logs.

Stages (one object, one verb each): ``parsers.read_flight(path) -> Flight``,
dataset building ``Flight -> Dataset``, the SNGP engine ``fit / predict``, identification and
diagnosis pipelines, and reports. See docs/signals.md for the frame and unit conventions.
"""
__version__ = "0.1.0"
