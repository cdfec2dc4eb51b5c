"""Words for a model a person reads: equations with readable numbers (prior terms as ⟨name⟩,
a leading number split off), improvement in percent, and the "vehicle type not declared" line.
Pure text: no pipeline imports; used by the stages that record sentences and by every report."""
from __future__ import annotations

import math
import re

from droneid.core.numerics import to_float

__all__ = ['improvement_pct', 'round_floats', 'display_term', 'readable_equation', 'split_leading_number', 'undeclared_line',
           'sentences']


def improvement_pct(reference: float, value: float) -> float:
    """How much lower ``value`` is than ``reference``, in percent of the reference."""
    if not (math.isfinite(reference) and math.isfinite(value)) or reference <= 0:
        return float("nan")
    return 100.0 * (reference - value) / reference


_LONG_FLOAT = re.compile(r"(?<![\w.])(\d+\.\d{5,}(?:e[+-]?\d+)?)")


def round_floats(text: str, sig: int = 4) -> str:
    """``text`` with every float of 5 or more decimals written to ``sig`` significant figures."""
    return _LONG_FLOAT.sub(lambda m: f"{float(m.group(1)):.{sig}g}", str(text))


def _top_level_sum(text: str) -> bool:
    """Whether ``text`` (sympy's str form) is a sum at the outermost level."""
    depth = 0
    for i, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0 and i > 0 and text[i - 1:i + 2] in (" + ", " - "):
            return True
    return False


def display_term(term: str, prior_symbols: dict | None = None, sig: int = 4) -> tuple[str, bool]:
    """(text, negated): a term with floats to ``sig`` figures and prior symbols as ⟨name⟩; a
    leading minus of a product is moved out (``negated``) and sums are parenthesised."""
    text = round_floats(term, sig)
    for sym in sorted(prior_symbols or {}, key=len, reverse=True):
        text = re.sub(rf"\b{re.escape(sym)}\b", f"⟨{prior_symbols[sym]}⟩", text)
    if _top_level_sum(text):
        return f"({text})", False
    negated = text.startswith("-")
    return text[1:] if negated else text, negated


_LEADING_NUMBER = re.compile(r"^(\d+(?:\.\d*)?(?:e[+-]?\d+)?)\*(?=\S)")


def readable_equation(target: str, coefficients: dict, prior_coefficients: dict, intercept,
                      prior_symbols: dict | None = None, sig: int = 4) -> str:
    """``target = β·⟨prior⟩ + ... + β·term + ... + β0``: prior features by name (also inside
    evolved terms), numbers to ``sig`` significant figures."""
    parts = [(float(b), f"⟨{name}⟩") for name, b in prior_coefficients.items()]
    for term, b in coefficients.items():
        if term in prior_coefficients:
            continue
        text, neg = display_term(term, prior_symbols, sig)
        b = -float(b) if neg else float(b)
        lead = _LEADING_NUMBER.match(text)
        if lead:  # 2.283·8.0*x -> 18.26·x
            b, text = b * float(lead.group(1)), text[lead.end():]
        parts.append((b, text))
    out = [f"{'-' if b < 0 else '+'} {abs(b):.{sig}g}·{term}" for b, term in parts]
    if intercept is not None and to_float(intercept) != 0.0:
        out.append(f"{'-' if intercept < 0 else '+'} {abs(intercept):.{sig}g}")
    body = " ".join(out) if out else "0"
    body = body[2:] if body.startswith("+ ") else "-" + body[2:] if body.startswith("- ") else body
    return f"{target} = {body}"


def split_leading_number(label: str, coefficient: float) -> tuple[float, str]:
    """A term label that starts with a number folded into its coefficient
    (``1.085e-10·4*roll**2`` -> ``4.34e-10·roll**2``)."""
    lead = _LEADING_NUMBER.match(label)
    if lead:
        return coefficient * float(lead.group(1)), label[lead.end():]
    return coefficient, label


def sentences(*parts: str) -> str:
    """The non-empty ``parts`` as one paragraph: each ends with a full stop (unless it ends with
    one, '!' or '?') and they are joined by a space."""
    out = [p.strip() for p in parts if p and p.strip()]
    return " ".join(p if p[-1] in ".!?" else p + "." for p in out)


def undeclared_line(undeclared: list[tuple[str, str, str]]) -> str:
    """One line for every flight whose log does not declare its vehicle type (``undeclared``:
    (flight name, what the data look like with the evidence, the same in short) in flight order):
    seven identical lines per run are one line naming the flights (the data-fitness check's
    :func:`droneid.dataset.suitability.assess`, identify's notes)."""
    if len(undeclared) == 1:
        name, judged, _ = undeclared[0]
        return f"{name}: vehicle type not declared by the log: {judged}; pass --vehicle to state it"
    names = ", ".join(n for n, _, _ in undeclared)
    looks = {short for _, _, short in undeclared}
    judged = (f"{next(iter(looks))} in each (droneid inspect LOG shows the evidence)" if len(looks) == 1
              else "; ".join(f"{n}: {j}" for n, j, _ in undeclared))
    return (f"{len(undeclared)} flights ({names}): vehicle type not declared by their logs: {judged}; "
            f"pass --vehicle to state it")

