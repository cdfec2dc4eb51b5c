"""A built-in effect is one module of priors/effect_catalogue/: discovery finds it at its
``order`` (the example of docs/extending.md, run as a plug-in), it is reachable by id (get_effect,
the diagnosis), a malformed module is refused, and every effect docs/diagnosis.md documents is
registered, in the catalogue's order."""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

import diag_synth as S
import priors.effect_catalogue as package
from droneid.diagnosis.diagnose import DiagnoseConfig, diagnose_datasets
from droneid.errors import ConfigError
from priors import effects
from priors.effects import CATALOGUE, get_effect

DOC = Path(__file__).parents[2] / "docs" / "diagnosis.md"

EXTENDING = Path(__file__).parents[2] / "docs" / "extending.md"


def _documented_plugin() -> str:
    """The example module of docs/extending.md ("An effect the diagnosis can test")."""
    text = EXTENDING.read_text(encoding="utf-8")
    m = re.search(r"```python\n(# priors/effect_catalogue/cubic_drag\.py\n.*?)```", text, flags=re.S)
    assert m, "the cubic_drag example is missing from docs/extending.md"
    return m.group(1)


PLUGIN = _documented_plugin()


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    d = tmp_path / "effects"
    d.mkdir()
    monkeypatch.setattr(package, "__path__", [*package.__path__, str(d)])
    effects.clear_cache()
    yield d
    effects.clear_cache()
    for name in ("cubic_drag", "misnamed", "no_effect"):
        sys.modules.pop(f"priors.effect_catalogue.{name}", None)


def test_the_catalogue_is_in_increasing_order_with_distinct_places():
    orders = [e.order for e in CATALOGUE.values()]
    assert orders == sorted(orders) and len(set(orders)) == len(orders), dict(
        (e.id, e.order) for e in CATALOGUE.values())


def test_every_module_is_one_effect_named_after_its_id():
    modules = {p.stem for p in Path(package.__file__).parent.glob("*.py") if not p.stem.startswith("_")}
    assert modules == set(CATALOGUE)
    for eid, e in CATALOGUE.items():
        assert sys.modules[f"priors.effect_catalogue.{eid}"].EFFECT is e


def test_every_documented_effect_is_registered_in_the_documented_order():
    text = DOC.read_text(encoding="utf-8")
    section = text[text.index("## The catalogue"):]
    section = section[:section.index("\n## ", 1)]
    documented = re.findall(r"^\| `(\w+)` \|", section, flags=re.M)
    assert documented, "no effect table found in docs/diagnosis.md"
    assert set(documented) <= set(CATALOGUE), set(documented) - set(CATALOGUE)
    assert documented == [eid for eid in CATALOGUE if eid in documented], "in the catalogue's order"


def test_one_new_module_is_a_new_effect(plugin_dir):
    (plugin_dir / "cubic_drag.py").write_text(PLUGIN)
    ids = list(CATALOGUE)
    assert ids.index("cubic_drag") == ids.index("anisotropic_drag") + 1     # order 65: after 60
    assert get_effect("cubic_drag").description == "drag growing with speed cubed"
    r = diagnose_datasets(S.make(None, seed=0), None, prior=S.TiltDragStub(),
                          config=DiagnoseConfig(generations=0, effects=("cubic_drag", "wind")))
    tried = set(r.effects_added) | set(r.not_detected) | set(r.untestable) | set(r.not_applicable)
    assert tried == {"cubic_drag", "wind"}


@pytest.mark.parametrize("name,body,match", [
    ("misnamed", PLUGIN, r"exports effect 'cubic_drag'; name the module after its id"),
    ("no_effect", "X = 1\n", r"must export EFFECT = Effect\(...\); got no EFFECT"),
])
def test_a_malformed_effect_module_is_refused(plugin_dir, name, body, match):
    (plugin_dir / f"{name}.py").write_text(body)
    with pytest.raises(ConfigError, match=match):
        list(CATALOGUE)
