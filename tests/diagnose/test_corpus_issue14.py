"""Issue 14's checks on MuJoCo-made data, end to end through ``refine`` from the naive scene
(slow: minutes each). No hidden effect: refine adds nothing. (The law-discrimination and
damped-chain cases of examples/hidden-effect are run by ``benchmarks/diagnosis.py --mode
refine``; they are not tests yet: see the benchmark's figures in docs/diagnosis.md.)"""
from __future__ import annotations

from pathlib import Path

import pytest

from physdsl.diagnose.refine import refine
from physdsl.syntax import load

NO_EFFECT = Path(__file__).parents[2] / "examples" / "no-effect"


def _effects(scene_path) -> set[tuple[str, tuple[str, ...]]]:
    return {(e.effect, tuple(e.target)) for e in load(scene_path).effects}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["throw_01", "rail_01", "spring_01"])
def test_refine_adds_nothing_where_nothing_is_hidden(name, tmp_path):
    naive = NO_EFFECT / name / "naive.phys"
    rounds = refine(naive, tmp_path / "refine", seed=0, echo=lambda line: None)
    assert _effects(rounds[-1].scene) == _effects(naive), [r.verdict for r in rounds]
    assert rounds[-1].rms_sigma < 1.2
