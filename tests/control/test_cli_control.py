"""``physdsl control`` from the command line on the cart example: the plan meets the goal, the
written control table drives the same scene to the same place, outputs are never overwritten
silently, and a scene without a goal is a usage error."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import physdsl
from physdsl.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "control_cart" / "cart.phys"


@pytest.mark.slow  # ~40 s; planning itself: tests/control/test_control.py
def test_control_writes_a_plan_that_the_planned_scene_replays(tmp_path, capsys):
    out = tmp_path / "plan"
    assert main(["control", str(EXAMPLE), "-o", str(out)]) == 0
    plan = json.loads((out / "plan.json").read_text())
    assert plan["met"] and plan["terms"][0]["error_m"] < 0.002
    # planned.phys reads control_rail.csv: a scene with nothing unknown left
    planned = physdsl.compile(out / "planned.phys")
    assert planned.unknown_names == ()
    end = np.asarray(planned.simulate({}).body_pos)[-1, 0]
    np.testing.assert_allclose(end, (0.5, 0.0, 0.5), atol=0.002)
    table = np.loadtxt(out / "control_rail.csv", delimiter=",", skiprows=1)
    assert table.shape == (10, 2) and np.all(np.diff(table[:, 1]) < 0)  # the falling ramp
    # the same output folder again: refused (exit 2), nothing overwritten
    before = (out / "plan.json").read_text()
    assert main(["control", str(EXAMPLE), "-o", str(out)]) == 2
    assert (out / "plan.json").read_text() == before


def test_a_scene_without_a_goal_is_a_usage_error(tmp_path, capsys):
    scene = tmp_path / "s.phys"
    scene.write_text(EXAMPLE.read_text().split("  goal {")[0] + "}\n")
    assert main(["control", str(scene), "-o", str(tmp_path / "o")]) == 2
    assert "no goal" in capsys.readouterr().err
