"""The plan: every choice made from the TRAINING flights before any SNGP run, ONE for identify and diagnose.

:func:`plan_inputs` picks the prior (``auto``: the most physical one the logs' signals
support, :func:`droneid.dataset.suitability.prior_for_flights`), sets the rotor-thrust prior's nominal thrust scale by
hover balance, chooses the thrust curve of a command-driven vehicle and the offset of the thrust
signals against the state in both directions by the calibrated block test of :mod:`droneid.fitting.decide`
(:func:`choose_offset`). :func:`diagnosis_datasets` builds, from that plan, the datasets and the
catalogue the diagnosis judges (the thrust inputs read at the chosen offset, the implausible
samples screened as every dataset is). ``droneid diagnose`` (:func:`droneid.diagnosis.diagnose.diagnose`)
and ``droneid identify`` (:func:`droneid.diagnosis.diagnose.plan_identification`, which folds the
diagnosed effects in) both call these two functions, so the same flights give the same prior,
offset, curve and effects. Rows held out as test data (``cuts``) are never seen.
The result is a frozen :class:`Plan`; :mod:`droneid.identify.pipeline` builds the target problems from it.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from priors.registry import PriorFeature, resolve_prior
from priors.thrust import COMMAND_SOURCES, NOMINAL_EXPO

from droneid.engine import runner
from droneid.dataset.data import Dataset
from droneid.dataset.builder import DatasetBuilder, _unique_names, reuse_datasets
from droneid.fitting.decide import decide, decide_family, holm_step_down
from droneid.dataset.suitability import prior_for_flights
from droneid.fitting.terms import prior_terms
from droneid.core.regression import blocked_cv, robust_fit
from droneid.dataset.validation import split_time_block, time_blocks
from droneid.core.targets import targets_for

if TYPE_CHECKING:
    from droneid.planning.settings import IdentifyConfig
    from droneid.fitting.thrust_curve import ThrustCurve
    from droneid.fitting.terms import TermModel

__all__ = ["Plan", "Effect", "OffsetDecision", "choose_offset", "choose_offsets", "OFFSET_GRID_S",
           "plan_inputs", "diagnosis_datasets", "holdout_cuts", "resolve_plan_prior", "train_rows",
           "dataset_builder", "fixed_plan", "PAPER_PRIOR"]

#: the prior of the paper's protocol (``study``, and ``--prior auto`` without a plan)
PAPER_PRIOR = "tilt-drag"


@dataclass(frozen=True)
class Effect:
    """An effect the diagnosis found on the training flights and folded into the prior features:
    its catalogue name, what it is physically, and its features per target."""
    effect: str
    physical: str
    features: Mapping[str, tuple[PriorFeature, ...]]


@dataclass(frozen=True)
class Plan:
    """What identify decided from the TRAINING flights before any SNGP run.

    prior : the PriorModel the search starts from; prior_reason : why (for ``auto``)
    targets : the targets identified; delays_s : {signal: delay s} of the thrust inputs
    delay_scores : {offset s: joint blocked-CV error of the refit prior, relative to no offset}
    offset : the :class:`OffsetDecision` behind ``delays_s`` (its test and interval), or None
    thrust_curve : the :class:`~droneid.fitting.thrust_curve.ThrustCurve` of a command-driven vehicle (its
        shape e, battery compensation, the log's declared values), or None
    effects : the diagnosis' folded effects (:class:`Effect`); diagnosis : its summary dict
    """
    prior: object
    prior_reason: str
    targets: tuple
    delays_s: dict = field(default_factory=dict)
    delay_scores: dict = field(default_factory=dict)
    effects: tuple["Effect", ...] = ()
    diagnosis: dict = field(default_factory=dict)
    notes: tuple = ()
    offset: "OffsetDecision | None" = None
    thrust_curve: "ThrustCurve | None" = None

    def lines(self) -> list[str]:
        """The plan in words, one line per decision, as identify and diagnose print it: the prior
        and why, the thrust curve, the thrust inputs' offset with its test, the diagnosis."""
        return [f"prior: {self.prior.name} ({self.prior_reason})", *self.notes]

    @property
    def thrust_signals(self) -> list[str]:
        """The prior's thrust inputs over the plan's targets (the signals the offset reads)."""
        return sorted({s for t in self.targets for s in self.prior.thrust_signals(t)})

    def admitted_offsets(self) -> list[float]:
        """The offsets of the grid the data do not reject besides the chosen one (s): those in the
        chosen offset's 95 % interval and, when the targets disagree on it, in the span of every
        target's own interval (a clock offset is one for the log: what each target admits, the
        vehicle constants must be reported over). Empty without an offset decision."""
        off = self.offset
        return off.admitted() if off is not None and self.thrust_signals else []

    def aligned(self, flights) -> list:
        """The training ``flights`` (in the order the plan was made from) with each flight whose
        clock the plan corrects (:attr:`OffsetDecision.clock`) moved in time on its thrust inputs,
        so that reading them at the chosen offset (``delays_s``) reads that flight's at the chosen
        offset plus its clock's difference from the others' (:attr:`OffsetDecision.applied`): a clock
        offset of one flight's streams corrected where every stage reads it. Other flights are
        returned as they are; pass the training flights only, in the plan's order (flights are
        matched by name)."""
        shifts = self.offset.shifts if self.offset is not None else {}
        return _clock_corrected(flights, self.thrust_signals, shifts) if shifts else list(flights)

    def record(self) -> dict:
        """The plan's decisions as result.json (identify's ``config``) and diagnosis.json
        (``plan``) record them: the prior used (its parameters and why), the input delays and the
        offset with its evidence, the thrust curve (:meth:`ThrustCurve.to_dict`)."""
        off = self.offset
        return {"prior_used": self.prior.name, "prior_params": dict(self.prior.params),
                "prior_reason": self.prior_reason, "delays_s": dict(self.delays_s),
                "delay_scores": {f"{k:.2f}": v for k, v in self.delay_scores.items()},
                "offset": ({"offset_s": off.offset_s, "interval_s": list(off.interval_s),
                            "evidence": off.decision.evidence if off.decision else "",
                            "per_target": {t: list(v) for t, v in off.per_target.items()},
                            "targets_agree": off.targets_agree,
                            "per_flight": {f: list(v) for f, v in off.per_flight.items()},
                            "flights_share": off.flights_share,
                            "own": {f: {"offset_s": d, "accepted": dec.accepted, "evidence": dec.evidence}
                                    for f, (d, dec) in off.own.items()},
                            "clock_s": {f: {"shift_s": d, "evidence": ev} for f, (d, ev) in off.clock.items()},
                            "unmoved": list(off.unmoved),
                            "applied_s": off.applied} if off is not None else None),
                "thrust_curve": self.thrust_curve.to_dict() if self.thrust_curve is not None else None}


def _hover_calibrated(prior, flights, cfg, cuts=None):
    """The prior with its nominal thrust scale set by hover balance on the training rows of v̇z
    (:meth:`priors.base.PriorModel.hover_calibrated`; a prior without one is returned as is)."""
    t = "vz_dot"
    if prior.hover_param is None or t not in prior.targets:
        return prior
    ds = train_rows(dataset_builder(cfg).build(list(flights), target=t, inputs=prior.inputs(t)), cuts)
    return prior.hover_calibrated(ds.columns(), t) if len(ds) else prior


def resolve_plan_prior(cfg, flights) -> tuple:
    """(PriorModel, reason) for the config's prior on these flights (``auto`` picks)."""
    return prior_for_flights(cfg.prior, flights, cfg.ts)


def dataset_builder(cfg, delays=None):
    """The DatasetBuilder of an identify config (its Ts and differentiator), with input delays."""
    return DatasetBuilder(ts=cfg.ts, method=cfg.method, delays_s=dict(delays or {}))


def fixed_plan(cfg, targets: Sequence[str] | None = None) -> Plan:
    """The plan of the paper's protocol, decided without looking at data: the named prior
    (``auto``: :data:`PAPER_PRIOR`), no input delays, no folded effects; ``targets`` (default:
    the config's, else every vehicle target the prior models)."""
    prior = resolve_prior(PAPER_PRIOR if cfg.prior == "auto" else cfg.prior)
    why = "the paper's prior" if cfg.prior == "auto" else "named by the user"
    return Plan(prior, why, targets_for(prior, targets or cfg.targets))


#: offsets of the thrust inputs against the state that are tried (s): from the input read 100 ms
#: later (its stream's stamps late) to 100 ms earlier (logged ahead of the thrust it makes)
OFFSET_GRID_S = tuple(round(0.01 * k, 2) for k in range(-10, 11))
#: family-wise level of the offset decision (:mod:`droneid.fitting.decide`, Holm over the grid)
OFFSET_ALPHA = 0.01
#: level of the offset's interval: the offsets the best one does not beat at this level
OFFSET_INTERVAL_ALPHA = 0.05


@dataclass(frozen=True)
class OffsetDecision:
    """The input offset chosen from the training flights, with its evidence.

    offset_s : chosen offset d (s; 0: none): the input is read at t − d, so d > 0 reads it earlier
        (it leads the thrust it makes), d < 0 later (its stream's stamps are |d| late: a clock
        correction of the merged log, not a model that needs the future)
    interval_s : (low, high) the offsets the best one is not significantly better than (95 %)
    scores : {d: joint held-out RMSE relative to d = 0}; decision : the Holm-controlled block test
        (:class:`droneid.fitting.decide.Decision`) of the best candidate, or None when none was testable
    per_target : {target: (best offset, low, high) s} each target's own best offset and the offsets
        it does not beat (95 %, the same rule as ``interval_s``): a clock offset is one for the
        log, so targets whose intervals do not overlap (:attr:`targets_agree` False) say the
        model lacks something in how thrust follows its signals (a motor lag, say) and the
        thrust and drag scales absorb it
    per_flight : {flight: (best, low, high) s}, the same for each training flight's own rows
        (the vehicle's terms fitted on the other flights: :func:`_per_flight_groups`)
    own : {flight: (its own best offset s, Decision)}: each training flight whose own best offset
        is not the chosen one, tested against it on that flight's (target, block) units by the rule
        of :mod:`droneid.fitting.decide` (Holm over every flight and every other offset of the grid,
        at :data:`OFFSET_ALPHA`), in the last round of :func:`choose_offsets` (none accepted there,
        or its rounds ran out: :attr:`unmoved`); like ``per_flight``, in each flight's own clock
        (the offset it would be read at, its shift included)
    clock : {flight: (shift s, evidence)}: the flights whose clock differs from the others' (their
        own offset was accepted in a round of :func:`choose_offsets`): their thrust inputs are
        moved by ``shift`` and so read at ``offset_s + shift`` (:attr:`applied`,
        :meth:`Plan.aligned`), a condition of that flight like its wind; the flights share the
        chosen offset (:attr:`flights_share`) when there is none
    unmoved : flights whose own offset still passed when :func:`choose_offsets`' rounds ran out
        (read at the chosen offset and said so)
    """
    offset_s: float
    interval_s: tuple
    scores: dict
    decision: object | None
    per_target: Mapping[str, tuple] = field(default_factory=dict)
    per_flight: Mapping[str, tuple] = field(default_factory=dict)
    own: Mapping[str, tuple] = field(default_factory=dict)
    clock: Mapping[str, tuple] = field(default_factory=dict)
    unmoved: tuple = ()

    @property
    def shifts(self) -> dict:
        """{flight: s} the thrust inputs of each flight with a clock of its own are moved by."""
        return {n: d for n, (d, _) in self.clock.items()}

    def admitted(self) -> list[float]:
        """The offsets of the grid the data do not reject besides the chosen one (s): those in the
        chosen offset's 95 % interval and, when the targets disagree on it, in the span of every
        target's own interval (a clock offset is one for the log: what each target admits, the
        coefficients are reported over)."""
        if self.decision is None:
            return []
        spans = [self.interval_s, *([v[1:] for v in self.per_target.values()] if not self.targets_agree else [])]
        lo, hi = min(a for a, _ in spans), max(b for _, b in spans)
        return [d for d in OFFSET_GRID_S if lo <= d <= hi and d != self.offset_s]

    @property
    def applied(self) -> dict:
        """{flight: offset s} of the training flights read at their own offset (:attr:`clock`; a
        clock offset between two log streams is a condition of one flight)."""
        return {n: round(self.offset_s + d, 3) for n, (d, _) in self.clock.items()}

    @property
    def flights_share(self) -> bool:
        """Whether every training flight is read at the chosen offset: none was moved, and no
        flight's own offset still beats it (:attr:`unmoved`)."""
        return not self.clock and not self.unmoved

    @property
    def targets_agree(self) -> bool:
        """Whether some offset lies in every target's own interval."""
        if len(self.per_target) < 2:
            return True
        return max(v[1] for v in self.per_target.values()) <= min(v[2] for v in self.per_target.values())

    def disagreement(self) -> str:
        """One sentence when the targets disagree on the offset, else ""."""
        if self.targets_agree:
            return ""
        each = ", ".join(f"{t} {1000 * b:+.0f} ms [{1000 * lo:+.0f}, {1000 * hi:+.0f}]"
                         for t, (b, lo, hi) in self.per_target.items())
        return (f"the targets disagree on the thrust inputs' offset ({each}): one clock offset cannot be "
                f"all of them, so the model lacks something in how thrust follows these signals (a motor "
                f"lag, say) and the thrust and drag scales absorb it")

    def sharing(self) -> str:
        """Whether the flights share the chosen offset, in words, with the per-flight tests."""
        tested = f"{len(self.own)} flight(s) whose own offset differs tested against it" if self.own else \
            "every flight's own best is the chosen offset"
        if self.flights_share:
            return f"the flights share it ({tested}; none beats it by the block test)"
        each = "; ".join(f"{n} moved by {1000 * d:+.0f} ms, read at {1000 * (self.offset_s + d):+.0f} ms ({ev})"
                         for n, (d, ev) in self.clock.items())
        left = (f"; the rounds ran out with {', '.join(self.unmoved)} still beating it: read at the chosen offset"
                if self.unmoved else "")
        return (f"NOT SHARED: these flights' clocks differ from the others' (a condition of the flight), and each "
                f"is moved by the difference its own offset showed: {each}{left}; flights not used in training "
                f"are read at the chosen {1000 * self.offset_s:+.0f} ms")

    def text(self, signals) -> str:
        names = ", ".join(signals)
        ev = self.decision.evidence if self.decision is not None else "no testable candidate"
        lo, hi = self.interval_s
        if not self.offset_s:
            return f"thrust inputs ({names}) read without offset: no offset in ±{1000 * OFFSET_GRID_S[-1]:.0f} ms " \
                   f"passes the block test on the training flights ({ev})"
        if self.offset_s > 0:
            what = f"delayed by {1000 * self.offset_s:.0f} ms (they lead the thrust they make)"
        else:
            what = (f"read {1000 * -self.offset_s:.0f} ms later: their stream's stamps are late by "
                    f"{1000 * -self.offset_s:.0f} ms (a clock correction of the merged log, not a model "
                    f"that needs the future)")
        text = f"thrust inputs ({names}) {what}; 95 % interval [{1000 * lo:.0f}, {1000 * hi:.0f}] ms; {ev}"
        if self.per_flight:
            own = ", ".join(f"{n} {1000 * b:+.0f} [{1000 * a:+.0f}, {1000 * c:+.0f}]" for n, (b, a, c) in self.per_flight.items())
            text += f". Each flight's own offset (ms): {own}: " + self.sharing()
        return text + (f". NOT ONE OFFSET: {self.disagreement()}" if not self.targets_agree else "")


def _offset_errors(job: "_OffsetSearch", offsets: Sequence[float]) -> dict:
    """{offset s: {target: (row keys, held-out residuals, blocks, (design, target less its fixed
    offset, lo, hi))}} of :func:`choose_offset` at ``offsets``: per target the prior's refit
    (``job.terms``: the unfitted :class:`~droneid.fitting.terms.TermModel`, over ``job.inputs``) by
    blocked CV on the training rows (``job.cuts``) of ``job.flights`` with the thrust
    ``job.signals`` read at the offset, and the least-squares problem behind it."""
    res = {}
    with reuse_datasets():      # each flight's intervals and screening once (or the caller's)
        for d in offsets:
            per = {}
            for t, terms in job.terms.items():
                # the prior's own inputs only (no extras: the rows do not depend on them)
                ds = train_rows(dataset_builder(job.cfg, {s: d for s in job.signals}).build(
                    list(job.flights), target=t, inputs=job.inputs[t], extras=()), job.cuts)
                blocks = time_blocks(ds.t, ds.flight, family=job.family, alpha=OFFSET_ALPHA)
                A, yy, lo, hi = terms._problem(ds.columns(), ds.y)
                err = yy - blocked_cv(A, yy, blocks, lo, hi)
                key = ds.flight.astype(np.int64) * 10**9 + np.round(ds.t * 1e4).astype(np.int64)
                per[t] = (key, err, blocks, (A, yy, lo, hi))
            res[float(d)] = per
    return res


@dataclass(frozen=True)
class _OffsetSearch:
    """What every offset of :func:`choose_offset` is scored on (shared by its workers): the
    training ``flights``, per target the prior's ``inputs`` and unfitted refit ``terms``, the
    thrust ``signals``, the identify config, the hold-out ``cuts`` and ``family``, the number of
    candidates the blocks are sized for (the grid's offsets other than 0)."""
    flights: tuple
    inputs: Mapping[str, tuple[str, ...]]
    terms: Mapping[str, "TermModel"]
    signals: tuple[str, ...]
    cfg: "IdentifyConfig"
    cuts: dict | None
    family: int


def choose_offset(train_flights, prior, targets, signals, cfg, cuts=None,
                  grid: Sequence[float] = OFFSET_GRID_S) -> OffsetDecision:
    """The offset of the thrust inputs by :mod:`droneid.fitting.decide`'s rule, on the training rows only.

    For each offset d of ``grid`` every target's refit prior gives held-out residuals (blocked CV,
    :func:`droneid.dataset.validation.n_blocks_for` time blocks per flight) on the rows all offsets share.
    The candidates d ≠ 0 are tested against d = 0 with Holm's control at :data:`OFFSET_ALPHA` over
    the whole grid; among the accepted the lowest held-out error wins. The interval is every
    offset the winner does not beat at :data:`OFFSET_INTERVAL_ALPHA`.

    The offsets are independent: with ``cfg.jobs`` > 1 they are split over that many forked
    workers (:func:`droneid.engine.runner.fork_map`; never a Dask cluster: the choice must not depend on
    another machine's arithmetic); the errors, and so the choice, are the same either way."""
    grid = [float(d) for d in grid]
    job = _OffsetSearch(tuple(train_flights), {t: tuple(prior.inputs(t)) for t in targets},
                        {t: prior_terms(prior, t) for t in targets}, tuple(signals), cfg, cuts, len(grid) - 1)
    n = min(cfg.jobs if cfg.jobs is not None else runner.default_jobs(), len(grid))
    found = {}
    for part in runner.fork_map(_offset_errors, job, [tuple(grid[i::n]) for i in range(n)], n):
        found.update(part)
    res = {d: found[d] for d in grid}   # the grid's order: the tests below and delay_scores follow it
    # the rows every offset has, per target; targets side by side (each target's (flight, block)
    # units numbered apart)
    shared = {t: _common_rows(res, t) for t in targets}
    names = _unique_names([f.name for f in train_flights])
    errs = {d: np.concatenate([shared[t][0][d] for t in targets]) for d in res}
    blocks = np.concatenate([i * 10**9 + shared[t][1] for i, t in enumerate(targets)]) if targets else np.zeros(0, int)
    rms = {d: float(np.sqrt(np.mean(e * e))) for d, e in errs.items()}
    scores = {d: rms[d] / rms[0.0] for d in rms}
    cands = {f"{1000 * d:+.0f} ms": errs[d] for d in errs if d != 0.0}
    if np.unique(blocks).size < 3 or not cands:
        return OffsetDecision(0.0, (0.0, 0.0), scores, None)
    per_target = _own_offsets({t: v[:2] for t, v in shared.items()})
    fam = decide_family(errs[0.0], cands, blocks, alpha=OFFSET_ALPHA)
    by_name = {f"{1000 * d:+.0f} ms": d for d in errs if d != 0.0}
    accepted = [n for n, dec in fam.items() if dec.accepted]
    best_name = min(fam, key=lambda n: (rms[by_name[n]], abs(by_name[n])))
    if accepted:
        best_name = min(accepted, key=lambda n: (rms[by_name[n]], abs(by_name[n])))
    best = by_name[best_name] if accepted else 0.0
    same = [d for d in errs if d == best or not decide(errs[d], errs[best], blocks, alpha=OFFSET_INTERVAL_ALPHA,
                                                         min_effect_pct=0.0).accepted]
    groups = _per_flight_groups(shared, names, best)
    per_flight = _own_offsets(groups)
    own = _flight_tests(groups, per_flight, best, len(grid) - 1)
    return OffsetDecision(best, (min(same), max(same)), scores, fam[best_name], per_target, per_flight, own)


def choose_offsets(train_flights, prior, targets, signals, cfg, cuts=None,
                   grid: Sequence[float] = OFFSET_GRID_S) -> OffsetDecision:
    """:func:`choose_offset` with each training flight's own clock: a flight whose own offset
    beats the chosen one by the block test (:attr:`OffsetDecision.own`) has its thrust inputs
    moved by the difference (its clock against the others'), and the offset is chosen again on
    the moved flights (the vehicle's terms of the others' profiles then fitted on flights whose
    clocks agree), until no flight's own passes, at most twice as many rounds as there are
    flights (a flight badly off distorts the others' profiles until it is moved, so one passes
    per round; :attr:`OffsetDecision.unmoved` names any the rounds left). The decision of the
    last round, on the flights as moved, its per-flight figures given back in each flight's own
    clock (the shift added: the offset that flight is read at)."""
    names = _unique_names([f.name for f in train_flights])
    clock: dict = {}
    rounds = max(2, 2 * len(train_flights))
    for k in range(rounds):
        moved = _clock_corrected(train_flights, signals, {n: d for n, (d, _) in clock.items()}, names)
        dec = choose_offset(moved, prior, targets, signals, cfg, cuts, grid)
        new = {n: (own - dec.offset_s, d.evidence) for n, (own, d) in dec.own.items() if d.accepted}
        if not new:
            break
        if k == rounds - 1:      # the rounds ran out: the decision stands on the flights as moved
            dec = replace(dec, unmoved=tuple(new))
            break
        for n, (dd, ev) in new.items():
            clock[n] = (round(clock.get(n, (0.0, ""))[0] + dd, 3), ev)
    shift = {n: d for n, (d, _) in clock.items()}
    per_flight = {n: tuple(round(v + shift.get(n, 0.0), 3) for v in t) for n, t in dec.per_flight.items()}
    own = {n: (round(d + shift.get(n, 0.0), 3), x) for n, (d, x) in dec.own.items()}
    return replace(dec, per_flight=per_flight, own=own, clock={n: v for n, v in clock.items() if v[0]})


def _clock_corrected(flights, signals: Sequence[str], shifts: Mapping[str, float], names=None) -> list:
    """``flights`` with the ``signals`` of each flight named in ``shifts`` ({flight: s}, names as
    :func:`droneid.dataset.builder._unique_names` gives them) moved later by its shift: read at an
    offset d, they give that flight's samples at d + shift."""
    flights = list(flights)
    if not shifts:
        return flights
    names = names or _unique_names([f.name for f in flights])
    out = []
    for name, f in zip(names, flights):
        dt = shifts.get(name, 0.0)
        moved = [f[s].shifted(dt) for s in signals if s in f]
        out.append(f.with_signals(*moved, note=f"thrust inputs moved by {1000 * dt:+.0f} ms: this flight's "
                                               f"clock offset against the others'") if dt and moved else f)
    return out


def _flight_tests(groups: Mapping[str, tuple], per_flight: Mapping[str, tuple], chosen: float,
                  n_other: int) -> dict:
    """{flight: (its own best offset s, Decision)} for the flights of ``per_flight`` whose own
    best is not ``chosen``: the own offset against the chosen one on the flight's units
    (``groups``: :func:`_per_flight_groups`), Holm's step-down over the flights, the family every
    flight times the ``n_other`` offsets of the grid besides the chosen (each flight's own was
    picked among them), at :data:`OFFSET_ALPHA`."""
    cand = {n: b for n, (b, _, _) in per_flight.items() if b != chosen}
    if not cand:
        return {}
    family = len(per_flight) * max(n_other, 1)

    def at(name, rank):
        errs, units = groups[name]
        return decide(errs[chosen], errs[cand[name]], units, alpha=OFFSET_ALPHA, family_size=family, rank=rank,
                      what=f"{name} at {1000 * cand[name]:+.0f} ms vs {1000 * chosen:+.0f} ms")
    return {n: (cand[n], dec) for n, dec in holm_step_down(at, list(cand)).items()}


def _common_rows(res: dict, target: str) -> tuple[dict, np.ndarray, np.ndarray, dict]:
    """({offset: held-out residuals}, units, flight index, {offset: (design, target, lo, hi)})
    of ``target`` on the rows every offset has (rows are ordered by flight, then time)."""
    keys = np.array(sorted(set.intersection(*(set(res[d][target][0].tolist()) for d in res))), dtype=np.int64)
    errs, problems = {}, {}
    for d in res:
        k, e, b, (A, y, lo, hi) = res[d][target]
        pos = np.searchsorted(k, keys)
        errs[d], problems[d] = e[pos], (A[pos], y[pos], lo, hi)
        if d == 0.0:
            blocks = b[pos]
    return errs, blocks, keys // 10**9, problems


def _own_offsets(groups: Mapping[str, tuple]) -> dict:
    """{group: (best, low, high)} for groups of rows ({name: ({offset: residuals}, units)}, e.g.
    a target's or a flight's): the group's lowest held-out error over the grid and the offsets
    that best does not beat at :data:`OFFSET_INTERVAL_ALPHA` on the group's own units (only with
    two or more groups, each with 3 units or more)."""
    if len(groups) < 2:
        return {}
    out = {}
    for name, (errs, blocks) in groups.items():
        if np.unique(blocks).size < 3:
            return {}
        rms = {d: float(np.sqrt(np.mean(e * e))) for d, e in errs.items()}
        best = min(rms, key=lambda d: (rms[d], abs(d)))
        same = [d for d in errs if d == best or not decide(errs[d], errs[best], blocks, alpha=OFFSET_INTERVAL_ALPHA,
                                                             min_effect_pct=0.0).accepted]
        out[name] = (best, min(same), max(same))
    return out


def _per_flight_groups(shared: Mapping[str, tuple], names: Sequence[str], chosen: float) -> dict:
    """{flight name: ({offset: residuals of every target on that flight's rows}, units)}: a
    profile of each flight's own offset. The vehicle's terms (its constants) are fitted on the
    OTHER flights at the ``chosen`` offset, once, and predict this flight's rows read at each
    offset of the grid (its clock offset is a condition of its own): held out by flight, and its
    drag cannot absorb its offset (a flight fitted alone lets the two trade off)."""
    out = {}
    for f in sorted({int(x) for _, _, fl, _ in shared.values() for x in np.unique(fl)}):
        errs, units = {}, []
        for i, (_, b, fl, problems) in enumerate(shared.values()):
            mine = fl == f
            units.append(i * 10**9 + b[mine])
            A0, y0, lo, hi = problems[chosen]
            beta = robust_fit(A0[~mine], y0[~mine], lo, hi).beta
            for d, (A, y, _, _) in problems.items():
                errs.setdefault(d, []).append(y[mine] - A[mine] @ beta)
        out[names[f] if f < len(names) else f"flight {f}"] = (
            {d: np.concatenate(v) for d, v in errs.items()}, np.concatenate(units))
    return out


def plan_inputs(train_flights, cfg, progress: Callable | None = None,
                cuts: dict | None = None) -> Plan:
    """Choose the prior, the thrust curve and the thrust inputs' offset from the training flights
    only (``cuts``: {flight index: time s} where a held-out test block starts: rows from there
    on are never seen here): the plan before the diagnosis, the one identify and diagnose share
    (``cfg``: an :class:`~droneid.planning.settings.IdentifyConfig`; its ``prior``, ``targets``, ``ts``,
    ``method``, ``delays`` and ``jobs`` are read)."""
    prior, reason = resolve_plan_prior(cfg, train_flights)
    prior = _hover_calibrated(prior, train_flights, cfg, cuts)
    notes = []
    prior, curve = _with_thrust_curve(prior, train_flights, cfg, cuts)
    targets = targets_for(prior, cfg.targets)
    thrust = sorted({s for t in targets for s in prior.thrust_signals(t)})
    delays, scores, decision = {}, {}, None
    if cfg.delays == "auto" and thrust:
        if progress:
            progress(0, 1, "choosing the thrust input offset")
        decision = choose_offsets(train_flights, prior, targets, thrust, cfg, cuts)
        scores = dict(decision.scores)
        # each flight's thrust inputs at its own clock (the flights that have one)
        aligned = _clock_corrected(train_flights, thrust, decision.shifts)
        if decision.offset_s or decision.clock:
            delays = {s: decision.offset_s for s in thrust} if decision.offset_s else {}
            if curve is not None and not curve.lag_s:   # the curve again, from the commands read at the offset
                prior, curve = _with_thrust_curve(prior, aligned, cfg, cuts, delays)
            elif curve is not None and decision.clock:  # a kept lag: again on the flights' own clocks
                prior, curve = _with_thrust_curve(prior, aligned, cfg, cuts)
        if curve is not None and not curve.lag_s:       # its interval over every offset the data admit
            # (a kept motor lag is the curve stage's own model of how the commands lead their thrust)
            from droneid.fitting.thrust_curve import over_offsets
            curve = over_offsets(curve, aligned, prior, cfg, cuts, thrust,
                                 [decision.offset_s, *decision.admitted()])
        notes.append(decision.text(thrust))
    if curve is not None:
        notes.insert(0, curve.text())
    elif prior.params.get("source") in COMMAND_SOURCES:
        notes.insert(0, f"thrust curve of the commands NOT chosen from the data (too few v̇z rows on the "
                        f"training flights): written with e = {prior.params.get('expo', NOMINAL_EXPO):g} "
                        f"(ArduPilot's default MOT_THST_EXPO), a shape nobody measured here")
    return Plan(prior, reason, targets, delays, scores, (), {}, tuple(notes), decision, curve)


def diagnosis_datasets(plan: Plan, flights, cfg, cuts: dict | None = None) -> tuple[dict, dict]:
    """({target: Dataset}, {catalogue id: the stage that decided it}) the diagnosis judges under
    ``plan`` on ``flights``: each
    target's dataset with the plan's prior inputs, its thrust inputs read at the chosen offset
    (``plan.delays_s``), every other signal in ``extra`` plus the motor speeds ``rpm1..`` every
    flight has (the most direct thrust signal for the effects), the rows before ``cuts``. The
    diagnosis leaves out what another stage of the plan decided: the battery compensation of a
    command-driven vehicle is the thrust curve's (:mod:`droneid.fitting.thrust_curve`)."""
    flights = list(flights)
    builder = dataset_builder(cfg, plan.delays_s)
    rpm = [f"rpm{i}" for i in range(1, 17)
           if flights and all(f"rpm{i}" in getattr(fl, "signals", ()) for fl in flights)]
    out = {}
    for t in plan.targets:
        inputs = tuple(plan.prior.inputs(t))
        ds = builder.build(flights, target=t, inputs=inputs)
        more = [n for n in rpm if n not in ds.columns()]
        if more:
            ds = builder.build(flights, target=t, inputs=inputs, extras=[*ds.extra, *more])
        out[t] = train_rows(ds, cuts)
    decided = {}
    if plan.thrust_curve is not None:
        kept = plan.thrust_curve.voltage
        decided["battery_sag"] = ("decided by the plan's thrust curve: battery compensation u·V/V_ref "
                                  + ("KEPT (the block test says it helps)" if kept else "not kept"))
    return out, decided


def _with_thrust_curve(prior, flights, cfg, cuts=None, delays=None):
    """(prior, ThrustCurve) for a command-driven prior: its thrust curve's shape and battery
    compensation chosen from the training flights (:func:`droneid.fitting.thrust_curve.choose_thrust_curve`),
    the nominal scale hover-calibrated again; (prior, None) for any other prior."""
    from droneid.fitting.thrust_curve import choose_thrust_curve, normalised

    curve = choose_thrust_curve(flights, normalised(prior, flights), cfg, cuts, delays)
    if curve is None:
        return prior, None
    prior = normalised(prior, flights).with_params(expo=round(curve.expo, 4),
                                                   v_ref=curve.v_ref if curve.voltage else None)
    return _hover_calibrated(prior, flights, cfg, cuts), curve


def train_rows(ds: Dataset, cuts: dict | None, test: bool = False) -> Dataset:
    """The rows before each flight's hold-out cut (``test``: from the cut on); all without cuts."""
    if not cuts:
        return ds
    cut = np.array([cuts.get(int(k), np.inf) for k in range(int(ds.flight.max()) + 1)]) if len(ds) else []
    before = ds.t < cut[ds.flight] if len(ds) else np.zeros(0, bool)
    return ds.subset(~before if test else before)


def holdout_cuts(train_flights, cfg, target: str, prior) -> dict:
    """{flight index: start time s of its held-out last ``cfg.test_fraction``} (time-block split
    of the undelayed dataset of ``target``)."""
    ds = dataset_builder(cfg).build(list(train_flights), target=target, inputs=prior.inputs(target))
    _, test = split_time_block(ds, test_fraction=cfg.test_fraction)
    return {int(k): float(np.min(test.t[test.flight == k])) for k in np.unique(test.flight)}
