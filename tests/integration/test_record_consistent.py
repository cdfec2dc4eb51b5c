"""One record (issue 29, item 4 / item 5 of "Why"): the terminal output, report.md, report.html and
result.json of ONE identify run state the same prior, constraint sets and input delays, and
those are the ones really used.

Before the fix the terminal said "constraints rotor-thrust's own" while report.md, report.html
and result.json said "constraints: paper", and the report named the prior "auto".

What "really used" means here, read from result.json: ``config.prior_used`` (the prior --prior
auto resolved to), ``targets.<t>.constraints`` (the constraint set each target's runs trained
on), ``config.delays_s`` (the input offsets applied; each final model's ``delays_s``). The set
names are checked against the prior independently: with ``--constraints paper`` (the prior's
own set) a prior with a fixed set names that set, and a prior that builds its sets from the data
names sets after itself.
"""
from __future__ import annotations

import html as htmllib
import json
import re

import pytest

from droneid.cli import main

from conftest import SAMPLE_LOGS

pytestmark = pytest.mark.slow

BUDGET = ["--runs", "1", "--generations", "200", "--population", "60", "--jobs", "1"]

#: (name, log, options): a rotor-thrust run with delays chosen by cross-validation (the case of
#: the issue), and a tilt-drag run without constraints or delays
RUNS = {
    "auto": ("rotor_climb_eight.tlog", []),
    "plain": ("paper_train_eight.tlog", ["--prior", "tilt-drag", "--constraints", "none", "--delays", "none",
                                         "--effects", "none"]),
}


@pytest.fixture(scope="module", params=sorted(RUNS))
def run(request, tmp_path_factory):
    """(result.json as a dict, terminal text, report.md text, report.html as plain text)."""
    import contextlib
    import io
    log, opts = RUNS[request.param]
    out = tmp_path_factory.mktemp(request.param)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        code = main(["identify", str(SAMPLE_LOGS / log), *opts, *BUDGET, "-q", "--report", str(out)])
    assert code == 0
    result = json.loads((out / "result.json").read_text(encoding="utf-8"))
    page = (out / "report.html").read_text(encoding="utf-8")
    md = (out / "report.md").read_text(encoding="utf-8")
    return result, buf.getvalue(), _md_plain(md), _html_plain(page)


def _html_plain(page: str) -> str:
    """report.html as text: scripts and styles dropped, each target heading kept as '## t'."""
    page = re.sub(r"<(style|script)[^>]*>.*?</\1>", " ", page, flags=re.S)
    page = re.sub(r"<h2>([^<]*)</h2>", r"\n## \1\n", page)
    return re.sub(r"[ \t]+", " ", htmllib.unescape(re.sub(r"<[^>]+>", " ", page)))


def _sections(text: str) -> dict:
    """{target: the text of its section} (sections start at '## target')."""
    parts = re.split(r"^## (\w+)\s*$", text, flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def _md_plain(md: str) -> str:
    """report.md with Markdown escapes and entities undone."""
    return htmllib.unescape(re.sub(r"\\(.)", r"\1", md))


def _header(text: str, where: str) -> dict:
    """prior, constraints clause and delays clause of the report's opening paragraph."""
    m = re.search(r"Prior '([^']+)' with .*?; constraints: (.*?); input offsets: (.*?); \d+ SNGP run", text, re.S)
    assert m, f"{where}: no 'Prior ... constraints: ...; input offsets: ...' paragraph"
    return {"prior": m.group(1), "constraints": m.group(2), "delays": m.group(3)}


def _set_names(clause: str) -> set:
    """The set names of a constraints clause: 'a, b (the prior's own, docs/priors.md)' -> {a, b}."""
    return {s.strip() for s in re.sub(r"\s*\(.*\)\s*$", "", clause).split(",") if s.strip()}


def _cli_header(text: str) -> dict:
    m = re.search(r"droneid identify: prior (\S+) with .*?, constraints (.*?), \d+ run\(s\)", text)
    assert m, f"terminal: no 'droneid identify: prior ... constraints ...' line:\n{text[:500]}"
    return {"prior": m.group(1), "constraints": m.group(2)}


def _ms(v: float) -> str:
    return f"{1000 * v:.0f} ms"


def test_the_prior_really_used_is_named_everywhere(run):
    result, cli, md, page = run
    used = result["config"]["prior_used"]
    assert used and used != "auto"
    assert _cli_header(cli)["prior"] == used
    assert _header(md, "report.md")["prior"] == used
    assert _header(page, "report.html")["prior"] == used


def test_the_constraint_sets_really_used_are_named_everywhere(run):
    from priors.registry import get_prior
    result, cli, md, page = run
    cfg = result["config"]
    per_target = {t: tr.get("constraints") for t, tr in result["targets"].items()}
    assert all(per_target.values()), f"result.json does not record each target's constraint set: {per_target}"
    used = set(per_target.values())
    if cfg["constraints"] == "none":
        assert used == {"none"}
    elif cfg["constraints"] == "paper":            # the prior's own set(s)
        prior = get_prior(cfg["prior_used"], **(cfg.get("prior_params") or {}))
        if callable(prior.constraints):
            assert all(n.split("+")[0] == prior.name for n in used), (used, prior.name)
        else:
            assert used == {str(prior.constraints)}, (used, prior.constraints)
        assert "paper" not in used or prior.constraints == "paper", used
    assert _set_names(_cli_header(cli)["constraints"]) == used
    assert _set_names(_header(md, "report.md")["constraints"]) == used
    assert _set_names(_header(page, "report.html")["constraints"]) == used
    # each target's own section names its set
    for text, where in ((md, "report.md"), (page, "report.html")):
        sections = _sections(text)
        sections.pop("Verdicts", None)       # the verdicts come first, in a section of their own
        assert set(sections) == set(per_target), (where, list(sections))
        for t, name in per_target.items():
            assert f"Constraints: {name}." in sections[t], f"{where}: {t} does not state its constraint set {name}"


def test_the_delays_really_used_are_stated_everywhere(run):
    result, cli, md, page = run
    delays = result["config"].get("delays_s") or {}
    finals = {t: (tr.get("final") or {}).get("delays_s") or {} for t, tr in result["targets"].items()}
    for t, d in finals.items():          # every final model was fitted with the plan's delays
        assert d == {k: v for k, v in delays.items() if k in d}, (t, d, delays)
    for text, where in ((md, "report.md"), (page, "report.html")):
        clause = _header(text, where)["delays"]
        if not delays:
            assert clause == "none", f"{where}: offsets {clause!r} but none were applied"
            assert "delayed inputs:" not in text, f"{where}: states a delayed input, none was applied"
            continue
        stated = dict(re.findall(r"(\w+) ([+−-]\d+ ms)", clause))
        assert stated == {k: f"{1000 * v:+.0f} ms" for k, v in delays.items()}, (where, clause)
        sections = _sections(text)
        for t, d in finals.items():
            for k, v in d.items():
                read_at = f"{k}(t {'−' if v > 0 else '+'} {_ms(abs(v))})"
                assert read_at in sections[t], f"{where}: {t} does not state {read_at}"
    if delays:
        note = re.search(r"inputs \(([^)]*)\) delayed by (\d+) ms", cli)
        assert note, "terminal: the applied delay is not stated"
        assert {s.strip() for s in note.group(1).split(",")} == set(delays)
        assert {_ms(v) for v in delays.values()} == {f"{note.group(2)} ms"}
