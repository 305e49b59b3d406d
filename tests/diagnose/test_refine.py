"""refine(): the loop finds the hidden effect, writes each round's scene and refine.json (slow:
several fits and refits)."""
from __future__ import annotations

import json

import pytest

from physdsl.diagnose.refine import refine
from physdsl.syntax import load

from .conftest import CASES, make_case

pytestmark = pytest.mark.slow


def test_refine_adds_the_hidden_drag_and_reaches_the_noise(tmp_path):
    make_case(tmp_path / "case", CASES["quadratic_drag"])
    scene = tmp_path / "case" / "naive.phys"
    before = scene.read_text()
    rounds = refine(scene, tmp_path / "out", max_rounds=2, backend="map", chains=2, warmup=200,
                    samples=200, confirm_top=2, echo=lambda *_: None)
    assert scene.read_text() == before  # the user's file is never edited
    assert len(rounds) == 2, [r.verdict for r in rounds]
    r0, r1 = rounds
    assert r0.added is None and r0.rms_sigma > 1.5
    assert r1.added == {"effect": "quadratic_drag", "target": "ball"}
    assert r1.rms_sigma <= 1.3 and r1.elpd > r0.elpd
    data = json.loads((tmp_path / "out" / "refine.json").read_text())
    assert [r["added"] for r in data["rounds"]] == [None, r1.added]
    assert [r["rms_sigma"] for r in data["rounds"]] == pytest.approx([r0.rms_sigma, r1.rms_sigma])
    new = load(tmp_path / "out" / "round-1" / "scene.phys")  # loads: its data were copied
    assert ("quadratic_drag", ("ball",)) in {(e.effect, tuple(e.target)) for e in new.effects}
    fix = (tmp_path / "out" / "round-0" / "diagnosis" / "fix.phys").read_text()
    assert fix.strip().startswith("effect quadratic_drag on ball")
