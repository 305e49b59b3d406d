"""A MuJoCo model as a plant (``plant.Plant``): the independent "real" system in the loop.

Each ``step`` writes the forces to the actuators that drive the named joints (``ctrl``,
divided by their gear) and advances MuJoCo by one control period of its own timesteps;
observations are the joints' ``qpos``/``qvel`` by name, with Gaussian noise if asked.
mujoco is an optional extra: imported when a plant is made.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import UsageError
from .plant import Observation


class MujocoPlant:
    """An MJCF file driven through its actuators (one per controlled joint)."""

    def __init__(self, path: str, period: float = 0.02, initial: Mapping[str, float] | None = None,
                 seed: int = 0, noise: float = 0.0):
        import mujoco  # optional extra (mujoco)

        self.mj = mujoco
        self.model = mujoco.MjModel.from_xml_path(str(path))
        self.data = mujoco.MjData(self.model)
        self.period = float(period)
        self.substeps = max(1, int(round(self.period / self.model.opt.timestep)))
        if not np.isclose(self.substeps * self.model.opt.timestep, self.period, rtol=1e-6):
            raise UsageError(f"plant period {period:g} s is not a whole number of the MJCF's "
                             f"timesteps ({self.model.opt.timestep:g} s)")
        self.initial = dict(initial or {})
        self.noise = float(noise)
        self.rng = np.random.default_rng(seed)
        self.joints = {self.model.joint(j).name: j for j in range(self.model.njnt)
                       if int(self.model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE),
                                                          int(mujoco.mjtJoint.mjJNT_SLIDE))}
        unknown = set(self.initial) - set(self.joints)
        if unknown:
            raise UsageError(f"plant has no joint {', '.join(sorted(unknown))}",
                             hint=f"its joints: {', '.join(self.joints)}")
        self.actuators = {}  # joint name -> (actuator id, gear)
        for a in range(self.model.nu):
            if int(self.model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT):
                name = self.model.joint(int(self.model.actuator_trnid[a, 0])).name
                self.actuators[name] = (a, float(self.model.actuator_gear[a, 0]))

    def reset(self) -> Observation:
        self.mj.mj_resetData(self.model, self.data)
        for name, value in self.initial.items():
            self.data.qpos[self.model.jnt_qposadr[self.joints[name]]] = value
        self.mj.mj_forward(self.model, self.data)
        return self._observe()

    def step(self, u: Mapping[str, float]) -> Observation:
        self.data.ctrl[:] = 0.0
        for target, value in u.items():
            if target not in self.actuators:
                raise UsageError(f"plant has no actuator on '{target}'",
                                 hint=f"actuated joints: {', '.join(self.actuators) or 'none'}")
            a, gear = self.actuators[target]
            self.data.ctrl[a] = value / gear
        for _ in range(self.substeps):
            self.mj.mj_step(self.model, self.data)
        return self._observe()

    def _observe(self) -> Observation:
        pos, vel = {}, {}
        for name, j in self.joints.items():
            pos[name] = float(self.data.qpos[self.model.jnt_qposadr[j]])
            vel[name] = float(self.data.qvel[self.model.jnt_dofadr[j]])
            if self.noise:
                pos[name] += self.noise * self.rng.standard_normal()
                vel[name] += self.noise * self.rng.standard_normal()
        return Observation(float(self.data.time), pos, vel)
