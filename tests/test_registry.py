"""Registries (physdsl/registry.py): one name per entry, entry points loaded once on the first
look-up, a broken plug-in named in the error; the built-in effects' declarations (what they
act on, their parameters) live in stdlib/ alone, one per registered effect."""
from __future__ import annotations

import sys

import numpyro.distributions as nd
import pytest

from physdsl.infer.base import BACKENDS
from physdsl.observe.kinds import OBSERVATION_KINDS
from physdsl.observe.sensor import SENSOR_FAULTS
from physdsl.physics.contact_models import CONTACT_MODELS
from physdsl.physics.effects import EFFECTS
from physdsl.physics.effects.base import declaration_text
from physdsl.registry import EFFECT_DECLARATIONS, Registry, RegistryError
from physdsl.syntax.dists import DISTRIBUTIONS, find
from physdsl.syntax.library import stdlib

GROUP = "physdsl.test_only"


def install(tmp_path, monkeypatch, module: str, source: str, entry: str) -> None:
    """``module`` (its ``source``) and a .dist-info naming ``entry`` under GROUP, on sys.path."""
    (tmp_path / f"{module}.py").write_text(source)
    dist = tmp_path / f"{module}-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{GROUP}]\n{entry}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, module, raising=False)


def test_a_second_entry_under_a_taken_name_is_refused():
    reg: Registry[int] = Registry(GROUP + ".none", "widget")
    reg.add("a", 1, "pkg.one")
    reg.add("a", 1, "pkg.one")  # the same module again (a re-import): harmless
    with pytest.raises(RegistryError, match=r"widget 'a' is registered twice \(pkg.one and pkg.two\)"):
        reg.add("a", 2, "pkg.two")
    assert dict(reg) == {"a": 1}


def test_entry_points_are_loaded_once_on_the_first_look_up(tmp_path, monkeypatch):
    install(tmp_path, monkeypatch, "reg_plugin_a", "LOADS = []\nLOADS.append(1)\nTHING = 'x'\n",
            "thing = reg_plugin_a:THING")
    reg: Registry[str] = Registry(GROUP, "thing")
    assert "reg_plugin_a" not in sys.modules  # nothing loaded before a look-up
    assert reg["thing"] == "x" and reg.origin("thing") == "reg_plugin_a"
    assert list(reg) == ["thing"] and len(reg) == 1
    assert sys.modules["reg_plugin_a"].LOADS == [1]


def test_a_broken_plugin_is_named_in_the_error(tmp_path, monkeypatch):
    install(tmp_path, monkeypatch, "reg_plugin_b", "raise ImportError('no numpy here')\n",
            "broken = reg_plugin_b")
    reg: Registry[str] = Registry(GROUP, "thing")
    with pytest.raises(RegistryError, match="cannot load thing 'broken' .*no numpy here"):
        "anything" in reg  # noqa: B015 - the look-up loads the entry points


def test_every_builtin_effect_matches_its_stdlib_declaration():
    """What a built-in effect acts on is registered with its physics; stdlib/effects/*.phys
    says the same (``on ...``), one file per registered effect and none without physics."""
    builtin = {n for n in EFFECTS if EFFECTS.origin(n).startswith("physdsl.physics.effects.")}
    declared = stdlib().effect_types
    assert builtin == set(declared)
    for name in builtin:
        assert set(declared[name][0].acts_on) == set(EFFECTS[name].acts_on), name
    assert not set(EFFECT_DECLARATIONS) & builtin


def test_a_plugin_declaration_is_written_from_its_registration():
    assert declaration_text("tug", ("body", "pair"), "  {\n  param k: N ~ half_normal(1 N)\n}\n") \
        == "effect_type tug on body or pair {\n  param k: N ~ half_normal(1 N)\n}\n"


def test_the_builtin_entries_register_themselves():
    assert {"map", "nuts", "hmc", "rmh"} <= set(BACKENDS)
    assert BACKENDS.origin("map") == "physdsl.infer.backends.map"
    assert find("normal") is nd.Normal and find("half_normal") is DISTRIBUTIONS["half_normal"]
    assert {"lcp", "compliant"} == set(CONTACT_MODELS)
    assert list(SENSOR_FAULTS) == ["delay", "gain", "offset"]  # the order they are applied in
    assert [SENSOR_FAULTS[k].off for k in SENSOR_FAULTS] == [0.0, 1.0, 0.0]
    assert {"position", "orientation", "velocity", "angular_velocity", "angle",
            "angular_rate"} == set(OBSERVATION_KINDS)
    assert OBSERVATION_KINDS["angle"][3:5] == (("angle",), "rad")  # columns, unit (the language's)
