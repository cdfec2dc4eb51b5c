"""droneid's Python API: read a log, compose an identification, use the result.

    import droneid
    flights = [droneid.read_log(p) for p in ("square_run1.csv", "square_run2.csv")]
    result = droneid.Identifier(prior="rotor-thrust", differentiator="central",
                                constraints="paper", effects="auto").fit(flights)
    print(result.targets["vx_dot"].verdict)
    score = result.predict(droneid.read_log("melon_run1.csv"))
    code = result.export("python")

The pieces are the CLI's, composed the way PySINDy composes ``SINDy(differentiation_method=…,
feature_library=…, optimizer=…)``: a prior (a name, ``FILE.toml:NAME`` or a
:class:`priors.base.PriorModel` object), a differentiator (``central``, ``forward``, ``savgol``,
``spline``), a constraint set (``paper``: the prior's own, ``none`` or a TOML file), effects
(``auto``: diagnosed and folded in, or ``none``) and every other setting of
:class:`droneid.identify.settings.IdentifyConfig`. docs/api.md walks through it.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

from parsers import read_flight

from droneid.logs.flight import Flight
from droneid.identify.pipeline import IdentificationResult, identify
from droneid.identify.settings import IdentifyConfig

__all__ = ["read_log", "Identifier"]


def read_log(path, **options) -> Flight:
    """One flight log read into a :class:`~droneid.logs.flight.Flight` (ENU world, FLU body, SI units,
    seconds), the format detected from the file. ``options``: ``format``, ``topics`` (MCAP role ->
    topic), ``body`` (Motive), ``column_map`` (CSV canonical name -> column), ``sysid`` (MAVLink),
    ``vehicle``, and the log's own convention when it is not droneid's: ``world_frame="ned"``,
    ``body_frame="frd"``, ``time_unit="ms"``, ``scales={"vx": "1/3.6"}`` (see
    :func:`parsers.read_flight`; :func:`droneid.logs.consistency.check_flight` says which a log needs)."""
    return read_flight(path, **options)


class Identifier:
    """An identification, composed from its parts; :meth:`fit` runs it.

    prior : the physical model the search starts from (``auto``, a built-in name,
        ``FILE.toml:NAME`` or a PriorModel object)
    differentiator : how v̇ is taken from the logged velocity (``central``, ``forward``,
        ``savgol``, ``spline``)
    constraints : ``paper`` (the prior's own set), ``none`` or a constraints TOML file
    effects, delays : ``auto`` (decided on the training flights by calibrated tests) or ``none``
    empirical, k_D : the user's empirical model every verdict compares with (tilt-drag, 0.28 1/s)
    quick : the quick budget instead of the paper's
    settings : any other :class:`~droneid.identify.settings.IdentifyConfig` field (``runs``, ``seed``,
        ``ts``, ``targets``, ``jobs``, …)
    """

    def __init__(self, prior="auto", *, differentiator: str = "central", constraints: str = "paper",
                 effects: str = "auto", delays: str = "auto", empirical: str = "tilt-drag", k_D: float = 0.28,
                 quick: bool = False, **settings):
        self.config = IdentifyConfig.make(quick=quick, prior=prior, method=differentiator, constraints=constraints,
                                          effects=effects, delays=delays, empirical=empirical, k_D=k_D, **settings)
        self.result_: IdentificationResult | None = None

    def fit(self, flights: Sequence[Flight], test: Sequence[Flight] | None = None,
            progress: Callable | None = None) -> IdentificationResult:
        """Identify every target from the training ``flights`` (``test``: flights reported, never
        used for a choice); the typed result, also kept as ``result_``."""
        self.result_ = identify(list(flights), list(test) if test else None, self.config, progress)
        return self.result_
