"""droneid's Python API: read a log, compose an identification, use the result.

    import droneid
    flights = [droneid.read_log(p) for p in ("square_run1.csv", "square_run2.csv")]
    result = droneid.Identifier(prior="rotor-thrust", differentiator="central",
                                constraints="prior", effects="auto").fit(flights)
    print(result.targets["vx_dot"].verdict)
    melon = droneid.read_log("melon_run1.csv")
    frame = result.predict(melon).to_frame("vx_dot")     # t_s, measured, final, ... (m/s²)
    errors = result.score(melon).targets["vx_dot"].errors["all"]   # RMSE, m/s²
    code = result.export("python")

The pieces are the CLI's, composed the way PySINDy composes ``SINDy(differentiation_method=…,
feature_library=…, optimizer=…)``: a prior (a name, ``FILE.toml:NAME`` or a
:class:`priors.base.PriorModel` object), a differentiator (``central``, ``forward``, ``savgol``,
``spline``), a constraint set (``prior``: the prior's own, ``none`` or a TOML file), effects
(``auto``: diagnosed and folded in, or ``none``) and every other setting of
:class:`droneid.planning.settings.IdentifyConfig`. docs/api.md walks through it.
"""
from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from dataclasses import fields

from parsers import read_flight

from droneid.errors import ConfigError, check_choice, did_you_mean
from droneid.logs.flight import Flight
from droneid.identify.pipeline import IdentificationResult, identify
from droneid.planning.settings import METHODS, IdentifyConfig

__all__ = ["read_log", "Identifier"]


def read_log(path, **options) -> Flight:
    """One flight log read into a :class:`~droneid.logs.flight.Flight` (ENU world, FLU body, SI units,
    seconds), the format detected from the file. ``options``: ``format``, ``topics`` (MCAP role ->
    topic), ``body`` (Motive), ``column_map`` (CSV canonical name -> column), ``sysid`` (MAVLink),
    ``vehicle``, and the log's own convention when it is not droneid's: ``world_frame="ned"``,
    ``body_frame="frd"``, ``time_unit="ms"``, ``scales={"vx": "1/3.6"}`` (see
    :func:`parsers.read_flight`; :func:`droneid.logs.consistency.check_flight` says which a log needs)."""
    return read_flight(path, **options)


#: the Identifier's own parameters -> the IdentifyConfig field each sets
_CONFIG_NAME = {"prior": "prior", "differentiator": "method", "constraints": "constraints", "effects": "effects",
                "delays": "delays", "empirical": "empirical", "k_D": "k_D", "quick": "quick"}


class Identifier:
    """An identification, composed from its parts; :meth:`fit` runs it.

    Parameters are stored as given (scikit-learn's convention: :meth:`get_params`,
    :meth:`set_params`) and validated when the identification is configured (:attr:`config`,
    :meth:`fit`).

    Parameters
    ----------
    prior : str or PriorModel, default "auto"
        The physical model the search starts from: ``auto`` (rotor-thrust where the logs have
        motor speeds, commands or thrust, tilt-drag otherwise), a built-in name,
        ``FILE.toml:NAME`` or a :class:`priors.base.PriorModel` object.
    differentiator : {"central", "forward", "savgol", "spline"}, default "central"
        How v̇ (m/s²) is taken from the logged velocity.
    constraints : str, default "prior"
        ``prior``: the prior's own constraint set (``paper`` is an alias: its earlier name, and
        how result.json records it); ``none``; or the path of a constraints TOML file.
    effects, delays : {"auto", "none"}, default "auto"
        ``auto``: effects folded in and the thrust inputs' delay (s) chosen on the training
        flights by calibrated tests; ``none``: the paper's protocol.
    empirical : str, default "tilt-drag"
        The user's empirical model every verdict compares with (a prior name or FILE.toml:NAME).
    k_D : float, default 0.28
        The empirical model's drag coefficient (1/s).
    quick : bool, default False
        The quick budget (3000 generations x population 200) instead of the paper's.
    **settings
        Any other :class:`~droneid.planning.settings.IdentifyConfig` field, e.g. ``runs`` (SNGP runs per
        target), ``seed``, ``ts`` (sampling period, s), ``targets`` ("vx_dot,vz_dot" or a
        tuple), ``test_fraction`` (held-out last fraction of each flight), ``jobs``.

    Attributes
    ----------
    result_ : IdentificationResult or None
        The result of the last :meth:`fit`.
    """

    def __init__(self, prior="auto", *, differentiator: str = "central", constraints: str = "prior",
                 effects: str = "auto", delays: str = "auto", empirical: str = "tilt-drag", k_D: float = 0.28,
                 quick: bool = False, **settings):
        self.prior = prior
        self.differentiator = differentiator
        self.constraints = constraints
        self.effects = effects
        self.delays = delays
        self.empirical = empirical
        self.k_D = k_D
        self.quick = quick
        self.settings = dict(settings)
        self.result_: IdentificationResult | None = None

    @classmethod
    def _param_names(cls) -> list[str]:
        """The named parameters of ``__init__``, in order (not ``settings``)."""
        return [p.name for p in inspect.signature(cls.__init__).parameters.values()
                if p.name != "self" and p.kind is not inspect.Parameter.VAR_KEYWORD]

    def get_params(self, deep: bool = True) -> dict:
        """The parameters as given: the named ones, then each of ``settings`` (``deep`` is
        accepted for scikit-learn's signature; no parameter is itself an estimator)."""
        return {**{k: getattr(self, k) for k in self._param_names()}, **self.settings}

    def set_params(self, **params) -> "Identifier":
        """Set parameters by name (a named one or an IdentifyConfig field); returns ``self``.
        The values are validated by :attr:`config` and :meth:`fit`, the names here."""
        named = self._param_names()
        extra = [f.name for f in fields(IdentifyConfig) if f.name not in _CONFIG_NAME.values()]
        for k, v in params.items():
            if k in named:
                setattr(self, k, v)
            elif k in extra:
                self.settings[k] = v
            else:
                raise ConfigError(f"The parameter {k!r} is not a parameter of Identifier"
                                  f"{did_you_mean(k, named + extra) or ' (see Identifier.get_params())'}.")
        return self

    def __repr__(self) -> str:
        defaults = {p.name: p.default for p in inspect.signature(type(self).__init__).parameters.values()}
        shown = {k: v for k, v in self.get_params().items() if k not in defaults or defaults[k] != v}
        return f"Identifier({', '.join(f'{k}={v!r}' for k, v in shown.items())})"

    @property
    def config(self) -> IdentifyConfig:
        """The validated settings these parameters make (ConfigError naming a bad one)."""
        self.set_params(**self.settings)   # every name checked, with "did you mean"
        check_choice("differentiator", self.differentiator, METHODS, owner="Identifier")
        given = {_CONFIG_NAME[k]: v for k, v in self.get_params().items() if k in _CONFIG_NAME}
        return IdentifyConfig.make(**given, **self.settings)

    def fit(self, flights: Sequence[Flight], test: Sequence[Flight] | None = None,
            progress: Callable | None = None) -> IdentificationResult:
        """Identify every target from the training flights.

        Parameters
        ----------
        flights : sequence of Flight
            The training flights: every choice is made on them.
        test : sequence of Flight, optional
            Flights only reported, never used for a choice (without them ``test_fraction``
            holds out the end of each training flight, or validation alone is reported).
        progress : callable, optional
            Called with progress messages (str).

        Returns
        -------
        IdentificationResult
            The typed result, also kept as ``result_``.
        """
        self.result_ = identify(list(flights), list(test) if test else None, self.config, progress)
        return self.result_
