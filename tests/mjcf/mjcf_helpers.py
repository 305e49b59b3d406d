"""Shared helpers of the MJCF tests: import through the CLI, roll out both sides."""
from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np

from physdsl.cli import main

DATA = Path(__file__).parent / "data"
sys.path.insert(0, str(Path(__file__).parents[1] / "physics"))
from mj import rollout  # noqa: E402  (tests/physics/mj.py: MuJoCo as the oracle)


def import_scene(tmp_path, model: str, *args: str) -> Path:
    """Import ``data/model`` into ``tmp_path/scene.phys`` with the CLI; return the scene path."""
    out = tmp_path / "scene.phys"
    assert main(["import", str(DATA / model), "-o", str(out), *args]) == 0
    return out


def joints(sim, out, names) -> np.ndarray:
    """Rollout columns (T, len(names)) of the named hinge/slider joints."""
    return np.asarray(out.joint_pos)[:, [sim.joint_names.index(n) for n in names]]


def mujoco_rollout(xml_text: str, steps: int, key: int | None = 0, ctrl=None):
    """qpos (steps + 1, nq) of MuJoCo from keyframe ``key`` (None: qpos0)."""
    m = mujoco.MjModel.from_xml_string(xml_text)
    qpos = m.key_qpos[key].copy() if key is not None else None
    qvel = m.key_qvel[key].copy() if key is not None else None
    return rollout(xml_text, steps, qpos=qpos, qvel=qvel, ctrl=ctrl)[0]
