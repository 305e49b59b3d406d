"""The files of a generated scene: trajectories and joint angles in the long CSV format that
``observe`` reads, rendered camera frames, and the table of every scene's parameters."""
from __future__ import annotations

import csv
import io as _io
from pathlib import Path
from typing import Sequence

import jax
import numpy as np

from .. import io
from ..render import files
from ..render.scene import drawn_bodies, render_frames

TRAJECTORY_COLUMNS = ("t", "body", "x", "y", "z", "qw", "qx", "qy", "qz")
JOINT_COLUMNS = ("t", "joint", "angle")
OUTPUT_RATE_HZ = 100.0  # trajectories are written at the world timestep or 100 Hz, the coarser


def _stride(times: np.ndarray) -> int:
    """Every how many simulated steps a row is written (<= OUTPUT_RATE_HZ)."""
    dt = float(times[1] - times[0]) if len(times) > 1 else 1.0
    return max(int(round((1.0 / OUTPUT_RATE_HZ) / dt)), 1)


def trajectory_csv(rollout, body_names: Sequence[str], moving: Sequence[bool]) -> str:
    """Long-format ``t,body,x,y,z,qw,qx,qy,qz`` of every moving body at <= 100 Hz."""
    t = np.asarray(rollout.t)
    k = _stride(t)
    pos = np.asarray(rollout.body_pos)[::k]
    quat = np.asarray(rollout.body_quat)[::k]
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(TRAJECTORY_COLUMNS)
    for i, ti in enumerate(t[::k]):
        for b, name in enumerate(body_names):
            if moving[b]:
                w.writerow([f"{ti:.6f}", name, *(f"{x:.9g}" for x in pos[i, b]),
                            *(f"{x:.9g}" for x in quat[i, b])])
    return buf.getvalue()


def joints_csv(rollout, joint_names: Sequence[str], kinds: Sequence[str]) -> str | None:
    """Long-format ``t,joint,angle`` of every hinge and slider joint (None if there are none)."""
    idx = [j for j, kind in enumerate(kinds) if kind in ("hinge", "slider")]
    if not idx:
        return None
    t = np.asarray(rollout.t)
    k = _stride(t)
    q = np.asarray(rollout.joint_pos)[::k]
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(JOINT_COLUMNS)
    for i, ti in enumerate(t[::k]):
        for j in idx:
            w.writerow([f"{ti:.6f}", joint_names[j], f"{q[i, j]:.9g}"])
    return buf.getvalue()


def parameters_csv(names: Sequence[str], table: np.ndarray) -> str:
    """``scene,NAME...``: one row of parameter values per generated scene."""
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["scene", *names])
    for i, row in enumerate(table):
        w.writerow([f"scene-{i + 1:04d}", *(f"{x:.10g}" for x in row)])
    return buf.getvalue()


def frames_folder(camera: str) -> str:
    """Folder of a generated scene's frames seen by ``camera``."""
    return f"frames-{camera}"


def camera_renderers(model) -> dict:
    """camera name -> (frame times, jitted ``(rollout, values) -> images``) for every camera
    of the scene (none when it has no body to draw). Times: the camera's observed frame
    times, else every 1/30 s over the simulated span."""
    scene = model.scene
    if not drawn_bodies(scene):
        return {}
    out = {}
    for cam in scene.cameras:
        times = files.frame_times(model, cam.name, None)
        out[cam.name] = (times, jax.jit(
            lambda rollout, values, name=cam.name, times=times: render_frames(
                scene, model.simulator, rollout, values, name, times)))
    return out


def write_camera_frames(folder: Path, times: np.ndarray, images) -> None:
    """PNG frames (and render.mp4) of one camera, with their times as ``times.csv``."""
    images = np.asarray(images)
    rate = 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else files.DEFAULT_FPS
    files.write_frames(images, folder, rate)
    io.write_text(folder / "times.csv", "t\n" + "".join(f"{t:.10g}\n" for t in times))
