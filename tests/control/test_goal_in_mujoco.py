"""The poster's experiment (differentiable LCP), as examples/control_pool states it: choose
the push of a cue ball so that the object ball it strikes is at a target at a given time;
replayed in MuJoCo (examples/control_pool/mujoco_replay.py: soft contacts, the dev corpus's
elastic ball-ball pair) the object ball ends within 2 cm of the target."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import physdsl
from physdsl.control import build, optimise

pytest.importorskip("mujoco")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "control_pool" / "pool.phys"
_spec = importlib.util.spec_from_file_location("pool_replay", EXAMPLE.parent / "mujoco_replay.py")
replay = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(replay)


@pytest.mark.slow  # a second of contact rollouts, screened and refined: minutes on a CPU
def test_the_push_found_through_the_collision_reaches_the_target_in_mujoco():
    model = physdsl.compile(EXAMPLE)  # the example: the object ball at (0.9, -0.1) m at 1 s
    (reach,) = model.scene.goal.terms
    plan = optimise(build(model, model.scene.goal))
    assert plan.met, plan.errors
    end = replay.replay_in_mujoco(float(plan.values["vx"]), float(plan.values["vy"]), reach.at)
    assert np.linalg.norm(end[:2] - np.array(reach.point[:2])) < 0.02, end
