"""Design of the DH arm (issue 17, item 4): ``physdsl design`` chooses the link lengths a2, a3
so the end-effector reaches three points computed from known true lengths; MuJoCo's forward
kinematics of the exported arm is the independent check."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from physdsl.cli import main
from physdsl.compile import load_source
from physdsl.mjcf.write import write_mjcf

mujoco = pytest.importorskip("mujoco")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "design_dh_arm"
SCENE = EXAMPLE / "design_dh_arm.phys"
TRUTH = json.loads((EXAMPLE / "truth.json").read_text())["unknowns"]


def mujoco_tips(scene, values) -> dict[str, np.ndarray]:
    """End-effector (marker = MJCF site) positions of the exported arm at its initial pose,
    by MuJoCo's forward kinematics alone."""
    xml, _ = write_mjcf(scene, values)
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("initial").id)
    mujoco.mj_kinematics(m, d)
    return {m.site(i).name: d.site_xpos[i].copy() for i in range(m.nsite)}


def target_errors(scene, values) -> np.ndarray:
    tips = mujoco_tips(scene, values)
    return np.array([np.linalg.norm(tips[t.target] - np.asarray(t.point)) for t in scene.goal.terms])


def test_the_targets_are_the_true_arms_kinematics_and_pin_down_the_lengths():
    scene = load_source(SCENE)
    assert scene.goal.decisions == ("a2", "a3") and len(scene.goal.terms) == 3
    # the targets are where MuJoCo puts the true arm's end-effector (rounded to 1 um) ...
    assert np.all(target_errors(scene, TRUTH) < 2e-6)
    # ... and a design 5 mm off in either length misses some target by more than 1 mm
    for name in ("a2", "a3"):
        off = dict(TRUTH, **{name: TRUTH[name] + 0.005})
        assert target_errors(scene, off).max() > 0.003


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    out = tmp_path_factory.mktemp("design") / "out"
    rc = main(["design", str(SCENE), "-o", str(out)])
    return rc, out


@pytest.mark.slow
def test_design_recovers_the_lengths_and_mujoco_reaches_the_targets(designed):
    rc, out = designed
    assert rc == 0
    plan = json.loads((out / "plan.json").read_text())
    chosen = {k: v["value"] for k, v in plan["chosen"].items()}
    design_error = {k: abs(chosen[k] - TRUTH[k]) for k in TRUTH}
    assert max(design_error.values()) < 1e-4, design_error
    assert plan["met"] and all(t["error_m"] < 1e-3 for t in plan["terms"])
    # independent oracle: MuJoCo forward kinematics of the arm exported with the chosen lengths
    errors = target_errors(load_source(SCENE), chosen)
    assert errors.max() < 1e-3, errors


@pytest.mark.slow
def test_planned_scene_is_the_designed_arm(designed):
    rc, out = designed
    planned = load_source(out / "planned.phys")
    assert planned.unknowns == () or not planned.unknowns
    assert target_errors(planned, {}).max() < 1e-3
