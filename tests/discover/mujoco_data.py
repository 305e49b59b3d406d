"""The three hidden laws made by MuJoCo instead of physdsl: the law applied before every 0.1 ms
RK4 step as ``xfrc_applied`` (ball) or ``qfrc_applied`` (hinge), as tools/make_data does for
wind and drag; same naive scenes, times and noise as ``cases.py``."""
from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from .cases import LawCase, write_csv

STEP = 1e-4

BALL_XML = """<mujoco><option timestep="{dt}" integrator="RK4" gravity="0 0 -9.81"/>
<worldbody><body name="ball" pos="{x} {y} {z}"><freejoint/>
<geom type="sphere" size="0.05" mass="0.2" contype="0" conaffinity="0"/></body></worldbody></mujoco>"""
PENDULUM_XML = """<mujoco><option timestep="{dt}" integrator="RK4" gravity="0 0 -9.81"/>
<worldbody><body name="arm" pos="0 0 0"><joint name="hinge" type="hinge" axis="0 1 0"/>
<geom type="sphere" pos="0 0 -1" size="0.05" mass="1" contype="0" conaffinity="0"/></body>
</worldbody></mujoco>"""


def _law_force(case: LawCase, d):
    """The true law at MuJoCo's state: (force on the ball) or (torque in the hinge)."""
    if case.kind == "body":
        v, x = d.qvel[:3], d.qpos[:3] - np.asarray(case.center)
        c = case.law
        f = np.zeros(3)
        if "v_sqrt_speed" in c:
            f += c["v_sqrt_speed"] * np.sqrt(np.linalg.norm(v)) * v
        if "d_inv2" in c:
            f += c["d_inv2"] * x / np.linalg.norm(x) ** 3
        return f
    return case.law.get("q3", 0.0) * d.qpos[0] ** 3


def simulate(case: LawCase) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free samples at the case's times: (N, 3) positions or (N, 1) angles."""
    if case.kind == "body":
        x, y, z = case.truth["ball.position"]
        model = mujoco.MjModel.from_xml_string(BALL_XML.format(dt=STEP, x=x, y=y, z=z))
        data = mujoco.MjData(model)
        data.qvel[:3] = case.truth["ball.velocity"]
    else:
        model = mujoco.MjModel.from_xml_string(PENDULUM_XML.format(dt=STEP))
        data = mujoco.MjData(model)
        data.qpos[0] = case.truth["hinge.initial"]
    times = np.linspace(0.0, case.duration, case.samples)
    out, t = [], 0.0
    mujoco.mj_forward(model, data)
    for ts in times:
        while t < ts - 1e-12:
            if case.kind == "body":
                data.xfrc_applied[1, :3] = _law_force(case, data)
            else:
                data.qfrc_applied[0] = _law_force(case, data)
            mujoco.mj_step(model, data)
            t += STEP
        out.append(data.qpos[:3].copy() if case.kind == "body" else data.qpos[:1].copy())
    return times, np.asarray(out)


def make_mujoco(case: LawCase, folder: Path, seed: int | None = None) -> Path:
    """Write the MuJoCo-made data (seeded noise) and the case's naive scene; its path."""
    folder.mkdir(parents=True, exist_ok=True)
    times, clean = simulate(case)
    rng = np.random.default_rng(case.seed if seed is None else seed)
    write_csv(folder / "data.csv", times, clean + rng.normal(0.0, case.noise, clean.shape),
              case.target, case.kind)
    path = folder / "naive.phys"
    path.write_text(case.naive())
    return path
