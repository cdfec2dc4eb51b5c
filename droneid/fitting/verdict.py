"""The verdict on a final model against the empirical one, beside the rule that makes it: one
sentence a user reads first, and its kind (:data:`VERDICT_KINDS`, the colour a report gives it).
A rung here is anything with the attributes of :class:`droneid.identify.ladder.Rung`
(``rmse_test``, ``rmse_validation``, ``constraint_rmse_test``, ``at_bound``). Errors are RMSEs in
m/s². The axis verdict of the rotational stage lives here too: one home for every verdict."""
from __future__ import annotations

import math
from dataclasses import dataclass

from droneid.core.numerics import to_float
from droneid.core.text import improvement_pct

__all__ = ['MARGIN_PCT', 'VERDICT_KINDS', 'MODEL_TO_USE', 'Verdict', 'verdict', 'axis_verdict', 'model_to_use']


#: a model is called better (worse) than its baseline only at an improvement of at least this much
#: (per cent of the baseline's error), in validation and on the test data alike
MARGIN_PCT = 5.0


#: what a verdict says, and the colour the report gives it
VERDICT_KINDS = {"better": "green", "no better": "grey", "worse": "red", "not to be trusted": "amber",
                 "no verdict": "grey"}


#: which model a verdict says to use (issue 36.6): the identified one where it wins (or where
#: nothing could be measured against it), the empirical one where it does not; "neither" where
#: predicting zero or the mean beats both (the NEITHER MODEL verdict)
MODEL_TO_USE = {"better": "identified", "no verdict": "identified", "no better": "empirical",
                "worse": "empirical", "not to be trusted": "empirical"}


def model_to_use(kind: str, use: str = "", text: str = "") -> str:
    """``use`` when given, else the model the verdict ``kind`` says to use (:data:`MODEL_TO_USE`;
    "neither" where the verdict ``text`` says NEITHER MODEL, as results written before issue 36.6
    say it; an unknown kind: "identified", as those results were used)."""
    if use:
        return use
    return "neither" if "NEITHER MODEL" in text else MODEL_TO_USE.get(kind, "identified")


@dataclass(frozen=True)
class Verdict:
    """One sentence a user reads first, its kind (a key of :data:`VERDICT_KINDS`) and the model it
    says to use (:func:`model_to_use`: "identified", "empirical" or "neither")."""
    kind: str
    text: str
    use: str = ""

    def __post_init__(self):
        object.__setattr__(self, "use", model_to_use(self.kind, self.use))

    def __str__(self) -> str:
        return self.text


def _physics_problems(final, reference, gamma: float) -> list[str]:
    """What makes a model untrustworthy as physics: coefficients the data pull outside their
    physical bounds, and a constraint error above γ that the prior's own refit does not explain."""
    out = [f"{k.strip('⟨⟩')} is pulled outside its physical range (held at {v:.3g})"
           for k, v in final.at_bound.items()]
    ec = to_float(final.constraint_rmse_test)
    ref = to_float(reference.constraint_rmse_test) if reference is not None else math.nan
    if math.isfinite(ec) and ec > gamma and not (math.isfinite(ref) and ec <= 1.1 * ref):
        out.append(f"it breaks the prior's constraints (e_c = {ec:.3g} > γ = {gamma:g})")
    return out


def verdict(target: str, final, empirical, evolved: bool, holdout: bool,
            y_spread: float = math.inf, *, reference=None, gamma: float = math.inf,
            trivial: dict | None = None) -> Verdict:
    """How the final model compares with the empirical model as given, on the test data (or,
    without any, on the training flights' validation blocks), with the absolute errors and the
    target's standard deviation. "better" needs all of: better in validation, every physical
    coefficient inside its bounds, e_c within γ (or no worse than the prior's own refit,
    ``reference``); otherwise the verdict says what is wrong and that the model is not to be
    trusted. A target that barely varies, or an error that cannot be measured, gives no verdict
    (never a "+100 %"). ``trivial``: {"zero": RMSE, "the training mean": RMSE} of predicting no
    model at all, measured where the models are (test rows, or validation blocks); when one of
    them is not beaten by :data:`MARGIN_PCT` by the better model, the verdict says so and advises
    neither."""
    te, ee = final.rmse_test, empirical.rmse_test
    va, ev = final.rmse_validation, empirical.rmse_validation
    has_test = math.isfinite(te) and math.isfinite(ee)
    where = ("on the held-out block" if holdout else "on the test flights") if has_test else \
        "on validation blocks of the training flights (no test data)"
    if not y_spread > 1e-3:
        return Verdict("no verdict", f"{target}: no verdict: the measured {target} barely varies (spread "
                       f"{y_spread:.2g}); these data cannot tell models apart")
    a, b = (te, ee) if has_test else (va, ev)
    if not (math.isfinite(a) and math.isfinite(b)) or b <= 0:
        return Verdict("no verdict", f"{target}: no verdict: the errors could not be measured")
    gain, vgain = improvement_pct(b, a), improvement_pct(ev, va)
    what = "identified model (with evolved terms)" if evolved else \
        "physical model (prior + effects; no evolved term survived validation)"
    sd = f"σ({target}) {y_spread:.3g}" if math.isfinite(y_spread) else ""
    errs = f"RMSE {a:.3g} vs {b:.3g} m/s²" + (f", {sd}" if sd else "")
    extra = f"; validation {vgain:+.0f} %" if has_test else ""
    problems = _physics_problems(final, reference, gamma)
    known = {k: v for k, v in (trivial or {}).items() if math.isfinite(to_float(v))}
    if known:
        name, e0 = min(known.items(), key=lambda kv: kv[1])
        # predicting no model is a baseline like any other: a model is better than it only by the
        # margin, so neither model is worth keeping when the better one is not (x500's hover: v̇x
        # 0.0157 against 0.0164 for zero, 4 %)
        # (an empirical model that IS no model, hover balance v̇z = 0, is judged by the rules below)
        same = any(math.isclose(b, float(v), rel_tol=1e-9) for v in known.values())
        if not same and not improvement_pct(e0, min(a, b)) >= MARGIN_PCT:
            return Verdict("no better", use="neither", text=f"{target}: NEITHER MODEL is {MARGIN_PCT:g} % better than "
                           f"predicting {name} {where}: RMSE "
                           f"{e0:.3g} m/s² for {name} vs {a:.3g} for the {what} and {b:.3g} for the empirical "
                           f"model" + (f" ({sd})" if sd else "") + f": neither explains {target} on these flights better "
                           f"than no model, so keep neither as a model of it (fly with more excitation, or the model "
                           f"lacks what moves it)"
                           + ("; besides, " + "; ".join(problems) if problems else ""))
    if problems:
        return Verdict("not to be trusted",
                       f"{target}: the {what} is NOT TO BE TRUSTED: " + "; ".join(problems)
                       + f" (it is {abs(gain):.0f} % {'better' if gain >= 0 else 'worse'} than the empirical model "
                       f"{where}: {errs}{extra}); keep the empirical model")
    outcome = _outcome(gain, vgain, has_test)
    if outcome == "better":
        return Verdict("better", f"{target}: the {what} beats the empirical model by {gain:.0f} % {where} "
                                 f"({errs}{extra})")
    if outcome == "test only":
        return Verdict("no better", f"{target}: the {what} is better {where} ({gain:+.0f} %: {errs}) but not "
                                    f"in validation on the training flights ({vgain:+.0f} %): keep the empirical model")
    if outcome == "even":
        return Verdict("no better", f"{target}: the {what} is no better than the empirical model {where} "
                                    f"({gain:+.0f} %: {errs}): keep the empirical model")
    why = ("the training flights do not represent the test flights" if has_test else
           "its fitted terms do not hold across the validation blocks")
    return Verdict("worse", f"{target}: the {what} is WORSE than the empirical model {where} ({gain:+.0f} %: "
                            f"{errs}{extra}): {why}; keep the empirical model")


def _outcome(gain: float, vgain: float, has_test: bool) -> str:
    """How a model compares with its baseline, the one rule of every verdict: "better" (by at
    least :data:`MARGIN_PCT` where it is judged and in validation), "test only" (better on the
    test data but not in validation), "even" (within the margin) or "worse". ``gain``: the
    improvement (%) on the test data, or in validation without any; ``vgain``: in validation."""
    if gain >= MARGIN_PCT:
        return "better" if not has_test or vgain >= MARGIN_PCT else "test only"
    return "even" if gain > -MARGIN_PCT else "worse"


_RUNG_WORDS = {"damping": "the rate decay", "attitude": "the attitude spring (the controller, opt-in)",
               "spinup": "the rate decay with the rotors' spin-up reaction", "torque": "the torque model"}


def axis_verdict(target: str, rung: str, val_held: float, val_model: float, test_held: float,
                 test_model: float, *, why_held: str = "") -> Verdict:
    """A rotational target's verdict: its body-rate SimErr (rad/s) with the rung its ladder took
    (``rung``: held, damping, attitude or torque) against its empirical baseline, the nominal
    rigid body with the rates held, in validation on held-out training flights and (where finite)
    on the test flights. ``held``: no rung passed its test (``why_held``: why, when the test could
    not pass at all), so there is nothing to compare. The model keeps the rung whatever the test
    flights say (they never choose); the verdict says how far to trust it."""
    if rung == "held":
        why = why_held or (f"no rotational term beat holding this body rate consistently over the held-out "
                           f"training flights' (flight, regime) cells (validation SimErr {val_held:.3g} rad/s held)")
        return Verdict("no better", f"{target}: {why}: the rate is held")
    what = _RUNG_WORDS.get(rung, rung)
    vgain = improvement_pct(val_held, val_model)
    has_test = math.isfinite(test_held) and math.isfinite(test_model) and test_held > 0
    gain = improvement_pct(test_held, test_model) if has_test else vgain
    if not (math.isfinite(gain) and math.isfinite(vgain)):
        return Verdict("no verdict", f"{target}: no verdict: the body-rate errors could not be measured")
    where = "on the test flights" if has_test else "on held-out training flights"
    errs = (f"SimErr {test_model:.3g} vs {test_held:.3g} rad/s held" if has_test
            else f"SimErr {val_model:.3g} vs {val_held:.3g} rad/s held")
    extra = f"; validation {vgain:+.0f} %" if has_test else ""
    outcome = _outcome(gain, vgain, has_test)
    if outcome == "better":
        return Verdict("better", f"{target}: {what} beats holding the rate by {gain:.0f} % {where} ({errs}{extra})")
    if outcome == "test only":
        return Verdict("no better", f"{target}: {what} is better {where} ({gain:+.0f} %: {errs}) but not in "
                                    f"validation on the training flights ({vgain:+.0f} %): do not count on it")
    if outcome == "even":
        return Verdict("no better", f"{target}: {what} is no better than holding the rate {where} "
                                    f"({gain:+.0f} %: {errs}{extra}): holding the rate does as well")
    why = ("the training flights do not represent the test flights" if has_test else
           "it does not hold across the held-out training flights")
    return Verdict("worse", f"{target}: {what} is WORSE than holding the rate {where} ({gain:+.0f} %: "
                            f"{errs}{extra}): {why}; hold the rate instead (--rotation none, or a simulator "
                            f"with ω̇ = 0 on this axis)")

