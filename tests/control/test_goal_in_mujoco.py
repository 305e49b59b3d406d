"""The poster's experiment (differentiable LCP), as examples/control_pool states it: choose
the push of a cue ball so that the object ball it strikes is at a target at a given time; replayed in MuJoCo (an independent
simulator: soft contacts, elastic ball-ball pair as in the dev corpus) the object ball ends
within 2 cm of the target."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import physdsl
from physdsl.control import build, optimise

mujoco = pytest.importorskip("mujoco")

R = 0.028575

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "control_pool" / "pool.phys"

# The same table in MuJoCo, written as the dev corpus writes its billiards: stiff soft
# contacts with the table (elliptic cone), an elastic frictionless ball-ball pair.
MJCF = f"""
<mujoco>
  <option timestep="5e-06" integrator="implicitfast" cone="elliptic" gravity="0 0 -9.81"/>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <geom name="table" type="plane" size="5 5 0.1"/>
    <body name="cue" pos="0 0 {R}"><freejoint/><geom name="cue" type="sphere" size="{R}" mass="0.17"/></body>
    <body name="object" pos="0.5 0.02 {R}"><freejoint/><geom name="object" type="sphere" size="{R}" mass="0.17"/></body>
  </worldbody>
  <contact>
    <pair geom1="table" geom2="cue" condim="3" friction="0.2 0.2 0.005 0.0001 0.0001" solref="0.00025 1"/>
    <pair geom1="table" geom2="object" condim="3" friction="0.2 0.2 0.005 0.0001 0.0001" solref="0.00025 1"/>
    <pair geom1="cue" geom2="object" condim="1" solref="-1e+08 0" solimp="0.99 0.99 0.001 0.5 2"/>
  </contact>
</mujoco>
"""


def replay_in_mujoco(vx: float, vy: float, until: float) -> np.ndarray:
    model = mujoco.MjModel.from_xml_string(MJCF)
    data = mujoco.MjData(model)
    cue = model.joint(0).dofadr[0]
    data.qvel[cue:cue + 6] = (vx, vy, 0.0, -vy / R, vx / R, 0.0)  # rolling, as in the scene
    mujoco.mj_step(model, data, nstep=int(round(until / model.opt.timestep)))
    return data.body("object").xpos.copy()


@pytest.mark.slow  # a second of contact rollouts, screened and refined: minutes on a CPU
def test_the_push_found_through_the_collision_reaches_the_target_in_mujoco():
    model = physdsl.compile(EXAMPLE)  # the example: the object ball at (0.9, -0.1) m at 1 s
    (reach,) = model.scene.goal.terms
    plan = optimise(build(model, model.scene.goal))
    assert plan.met, plan.errors
    end = replay_in_mujoco(float(plan.values["vx"]), float(plan.values["vy"]), reach.at)
    assert np.linalg.norm(end[:2] - np.array(reach.point[:2])) < 0.02, end
