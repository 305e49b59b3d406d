"""Issue 14's articulated cases end to end through ``refine`` from the naive scene (slow: each
refit of an articulated scene takes minutes on one core).

- ``hinge_coulomb`` (MuJoCo, frictionloss 0.06 N m on a pendulum's hinge): viscous against
  Coulomb in one hinge, the right one named (Coulomb friction, not damping, on the hinge),
  refitted to the truth;
- ``damped_chain`` (MuJoCo, 0.003 N m s/rad in every hinge of a 4-link chain): damping on every
  hinge (the group candidate), at the noise, the truth inside each 90% interval.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from physdsl.diagnose.refine import refine
from physdsl.syntax import load

pytestmark = pytest.mark.slow

HIDDEN = Path(__file__).parents[2] / "examples" / "hidden-effect"


def _effects(scene_path) -> set[tuple[str, tuple[str, ...]]]:
    return {(e.effect, tuple(e.target)) for e in load(scene_path).effects}


def _summary(scene_path) -> dict:
    with (Path(scene_path).parent / "fit" / "summary.csv").open() as f:
        return {r["name"]: r for r in csv.DictReader(f)}


def _refine(name, tmp_path):
    """(truth, final round, history, effects added) of refine on hidden-effect case ``name``."""
    folder = HIDDEN / name
    truth = json.loads((folder / "truth.json").read_text())
    rounds = refine(folder / "naive.phys", tmp_path / "refine", seed=0, echo=print)
    final = rounds[-1]
    history = [(r.action, r.added, r.replaced, round(r.rms_sigma, 2)) for r in rounds]
    return truth, final, history, _effects(final.scene) - _effects(folder / "naive.phys")


def test_refine_names_coulomb_not_viscous_friction_in_the_hinge(tmp_path):
    truth, final, history, added = _refine("hinge_coulomb", tmp_path)
    assert added == {("joint_friction", ("hinge",))}, history  # the right law, alone
    assert final.rms_sigma <= 1.2, history
    row = _summary(final.scene)["joint_friction@hinge.torque"]
    assert float(row["q5"]) <= truth["parameters"]["joint_friction@hinge.torque"] <= float(row["q95"]), row


def test_refine_finds_damping_in_every_hinge_of_the_chain(tmp_path):
    truth, final, history, added = _refine("damped_chain", tmp_path)
    assert added == {("joint_damping", (f"hinge{i}",)) for i in range(1, 5)}, history
    assert final.rms_sigma <= 1.2, history
    rows = [r for name, r in _summary(final.scene).items() if "joint_damping" in name]
    assert rows, "no damping unknown in the final fit"
    b = truth["parameters"]["joint_damping@hinge1.coefficient"]
    for r in rows:  # one shared strength, or one per hinge: each covers the truth
        assert float(r["q5"]) <= b <= float(r["q95"]), r
