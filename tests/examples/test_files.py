"""Every bundled example is complete and self-consistent: its .phys parses, the data files it
names exist next to it in the documented long format, and each hidden-effect case names a
standard-library effect on a real target that its naive scene leaves out."""
from __future__ import annotations

import csv
import json
import re

import pytest

from conftest import EXAMPLES, HIDDEN, ROOT

SCENES = sorted(p for p in EXAMPLES.rglob("*.phys"))
# examples of using a model (control, design) state a goal and measure nothing
GOALS = [p for p in SCENES if re.search(r"^\s*goal\s*\{", re.sub(r"#[^\n]*", "", p.read_text()), re.M)]
# an experiment to design (a free control `values ~`, no goal) measures, but its control is
# chosen (physdsl design-experiment), not a truth
DESIGNS = [p for p in SCENES if p not in GOALS
           and re.search(r"values\s*~", re.sub(r"#[^\n]*", "", p.read_text()))]
FITTED = [p for p in SCENES if p not in GOALS and p not in DESIGNS]
CASES = sorted(p for p in HIDDEN.iterdir() if p.is_dir())
OBSERVE = re.compile(r'observe\s+(\w+)\.(\w+)\s+from\s+"([^"]+)"(?:\s+where\s+(\w+)\s*==\s*"([^"]+)")?')
COLUMNS = {"position": ("x", "y", "z"), "orientation": ("qw", "qx", "qy", "qz"), "angle": ("angle",)}


def _code(path):
    """The .phys text without comments."""
    return re.sub(r"#[^\n]*", "", path.read_text())


def _stdlib_effects() -> set[str]:
    table = (ROOT / "docs" / "language.md").read_text().split("## Effects of the standard library")[1]
    return set(re.findall(r"^\| (\w+) \|", table, flags=re.M)) - {"effect"}


def test_the_expected_examples_are_bundled():
    names = {p.parent.name for p in SCENES if p.parent.parent == EXAMPLES}
    assert {"thrown_ball", "bouncing_ball", "sliding_block", "pendulum", "spring_mass", "billiards",
            "double_pendulum", "cart_pole", "ball_chain", "dh_arm"} <= names
    assert len(CASES) >= 5


@pytest.mark.parametrize("path", SCENES, ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_scene_parses(path):
    parser = pytest.importorskip("physdsl.syntax.parser")
    module = parser.parse(path.read_text(), str(path))
    assert module is not None


@pytest.mark.parametrize("path", FITTED, ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_observed_data_exist_in_long_format(path):
    obs = OBSERVE.findall(_code(path))
    assert obs, "an example observes something"
    many = re.search(r'experiments\s+\w+\s+from\s+"([^"]+)"', _code(path))  # one folder each
    folders = sorted({p.parent for p in path.parent.glob(many.group(1))}) if many else [path.parent]
    for target, quantity, file, key, value in obs:
        assert not file.startswith("/") and ".." not in file  # next to the scene, relative
        count = 0
        for folder in folders:
            data = folder / file
            assert data.is_file()
            assert data.stat().st_size < 100_000
            with data.open() as f:
                rows = list(csv.DictReader(f))
            assert rows[0].keys() >= {"t", *COLUMNS[quantity]}
            assert key in rows[0] and key in ("body", "joint")
            mine = [r for r in rows if r[key] == value]
            count += len(mine)
            t = [float(r["t"]) for r in mine]
            assert t == sorted(t) and t[0] == 0.0
        assert value == target and count >= 50


@pytest.mark.parametrize("path", FITTED, ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_every_example_has_a_truth_naming_its_unknowns(path):
    truth = json.loads((path.parent / "truth.json").read_text())
    unknowns = truth["unknowns"] if "unknowns" in truth else {k: truth["parameters"][k] for k in truth["naive_unknowns"]}
    code = _code(path)
    for name in unknowns:
        if "@" in name:  # effect parameter: the effect acts on the target in this scene
            effect, rest = name.split("@")
            target, param = rest.rsplit(".", 1)
            sugar = {"contact_friction": "friction", "restitution": "restitution"}.get(effect)
            pair = target.replace(",", r",\s*")
            assert re.search(rf"effect\s+{effect}\s+on\s+\(?{pair}\)?\s*\{{[^}}]*{param}\s*~", code) or (
                sugar and re.search(rf"contact\s+{pair}\s*\{{[^}}]*{sugar}\s*~", code)), name
        elif "." in name:  # a field with a prior, inside its body or joint block
            owner, field = name.split(".")
            assert re.search(rf"(body|joint)\s+{owner}\b[^}}]*\b{field}\s*~", code), name
        else:
            assert re.search(rf"param\s+{name}\s*~", code), name


@pytest.mark.parametrize("case", CASES, ids=lambda p: p.name)
def test_hidden_effect_case_is_complete(case):
    truth = json.loads((case / "truth.json").read_text())
    effect, target = truth["hidden_effect"]["effect"], truth["hidden_effect"]["target"]
    assert effect in _stdlib_effects()
    code = _code(case / "naive.phys")
    material = target.endswith(",*")  # every contact pair of one fixed body, one coefficient
    for name in target.split(",")[: 1 if material else None]:
        looped = re.sub(r"\d+$", r"\\{\\w\\}", name)  # hinge1 declared in a loop as hinge{i}
        assert re.search(rf"\b(body|ground)\s+{name}\b|\bjoint\s+({name}|{looped})\s*:", code), name
    # the naive scene leaves the effect out, also as contact sugar
    assert not re.search(rf"effect\s+{effect}\b", code)
    if "," in target and not material:
        assert not re.search(r"contact\s+" + target.replace(",", r",\s*"), code)
    if material:
        strength = [k for k in truth["parameters"] if k == f"{target[:-2]}_{effect}"]
    else:
        strength = [k for k in truth["parameters"] if k.startswith(f"{effect}@{target}.")]
    assert len(strength) == 1
    readme = [ln for ln in (case / "README.md").read_text().splitlines() if ln.strip()]
    assert readme[0].startswith("# ") and 2 <= len(readme) - 1 <= 5


@pytest.mark.parametrize("path", FITTED, ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_scene_resolves_with_the_unknowns_of_its_truth(path):
    syntax = pytest.importorskip("physdsl.syntax")
    scene = syntax.load(path)
    truth = json.loads((path.parent / "truth.json").read_text())
    expected = truth["unknowns"] if "unknowns" in truth else truth["naive_unknowns"]
    assert {u.name for u in scene.unknowns} == set(expected)


@pytest.mark.parametrize("path", GOALS, ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_a_goal_example_resolves_with_its_goal_and_something_to_choose(path):
    syntax = pytest.importorskip("physdsl.syntax")
    scene = syntax.load(path)
    assert scene.goal is not None and scene.goal.terms
    controls = [u for u in scene.unknowns if u.name.startswith("control_force@")]
    assert controls or scene.goal.decisions
