"""The pool shot's table in MuJoCo, written as the dev corpus writes its billiards (stiff soft
contacts with the table, elliptic cone; an elastic frictionless ball-ball pair; 5 µs steps):
the independent simulator that a chosen push is replayed in (tests/control, benchmarks/control.py).
"""
from __future__ import annotations

import mujoco
import numpy as np

R = 0.028575

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
    """The object ball's position after ``until`` s, the cue struck rolling at (vx, vy) m/s."""
    model = mujoco.MjModel.from_xml_string(MJCF)
    data = mujoco.MjData(model)
    cue = model.joint(0).dofadr[0]
    data.qvel[cue:cue + 6] = (vx, vy, 0.0, -vy / R, vx / R, 0.0)  # rolling, as in the scene
    mujoco.mj_step(model, data, nstep=int(round(until / model.opt.timestep)))
    return data.body("object").xpos.copy()
