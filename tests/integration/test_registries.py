"""Every registry is reachable by name from the CLI: readers (--format), priors (--prior),
differentiators (--method) and effects (--only). A name that reaches its registry either works
or fails with the registry's own one-line error about the data, never 'unknown ...'."""
import pytest

from conftest import SAMPLE_LOGS
from droneid.cli import main
from droneid.core.differentiation import DIFFERENTIATORS
from parsers import READERS
from priors.effects import CATALOGUE
from priors.registry import PRIORS

LOG = SAMPLE_LOGS / "paper_train_eight.tlog"


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("fmt", sorted(READERS))
def test_every_reader_by_name(capsys, fmt):
    code, out, err = run(capsys, "inspect", LOG, "--format", fmt)
    assert code in (0, 2) and "unknown" not in err.lower() and "invalid choice" not in err
    assert code == 0 if fmt == "tlog" else len(err.strip().splitlines()) == 1  # the reader's own verdict


@pytest.mark.parametrize("prior", sorted(PRIORS))
def test_every_prior_by_name(capsys, tmp_path, prior):
    code, out, err = run(capsys, "-q", "identify", LOG, "--prior", prior, "--runs", "1", "--generations", "50",
                         "--population", "40", "--jobs", "1")
    assert "unknown prior" not in err and "invalid choice" not in err
    if prior == "unicycle":  # the TurtleBot's: the drone log has no v_f command, said in one line
        assert code == 2 and len(err.strip().splitlines()) == 1
    else:
        assert code == 0 and f"prior {prior}" in out


@pytest.mark.parametrize("method", sorted(DIFFERENTIATORS))
def test_every_differentiator_by_name(capsys, tmp_path, method):
    code, _, err = run(capsys, "dataset", LOG, "--target", "vx_dot", "--method", method, "-o", tmp_path / "t.csv")
    assert code == 0, err
    assert (tmp_path / "t.csv").is_file()


def test_every_effect_by_name(capsys):
    ids = ",".join(sorted(CATALOGUE))
    code, out, err = run(capsys, "diagnose", LOG, "--only", ids, "--sngp-generations", "0", "--json")
    assert code == 0, err
    import json
    doc = json.loads(out)
    seen = set(doc["effects_added"]) | set(doc["not_detected"]) | set(doc["untestable"]) \
        | set(doc.get("not_applicable") or {})
    assert seen == set(CATALOGUE)
