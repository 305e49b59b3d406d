"""MuJoCo as an oracle: run an MJCF model and record qpos/qvel (and body poses)."""
from __future__ import annotations

import mujoco
import numpy as np


def rollout(xml: str, steps: int, qpos=None, qvel=None, ctrl=None):
    """(qpos (T+1, nq), qvel (T+1, nv), xpos (T+1, nbody, 3), xquat) of ``steps`` mj_step calls.

    ``ctrl(k)`` gives the control vector applied during step k (held over the step)."""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    if qpos is not None:
        d.qpos[:] = qpos
    if qvel is not None:
        d.qvel[:] = qvel
    mujoco.mj_forward(m, d)
    Q, V, X, R = [d.qpos.copy()], [d.qvel.copy()], [d.xpos.copy()], [d.xquat.copy()]
    for k in range(steps):
        if ctrl is not None:
            d.ctrl[:] = ctrl(k)
        mujoco.mj_step(m, d)
        Q.append(d.qpos.copy()), V.append(d.qvel.copy()), X.append(d.xpos.copy()), R.append(d.xquat.copy())
    return np.array(Q), np.array(V), np.array(X), np.array(R)


def model_data(xml: str):
    m = mujoco.MjModel.from_xml_string(xml)
    return m, mujoco.MjData(m)
