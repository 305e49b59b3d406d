"""``sample``: N concrete scenes drawn from a program's priors, simulated, with a parameter table."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import jax
import numpy as np

from .. import io, syntax
from ..compile import compile_scene
from ..errors import UsageError
from ..export.program import ensure_duration, rebase_paths, scene_decl, with_items
from ..syntax import ast as A
from ..syntax.loops import unroll_module
from .files import (camera_renderers, frames_folder, joints_csv, parameters_csv, trajectory_csv,
                    write_camera_frames)
from .values import columns, concrete_text, parameter_values


@dataclass(frozen=True)
class SampleResult:
    """What ``sample`` wrote: the folder, one concrete scene per draw, the parameter table."""

    outdir: Path
    scenes: tuple[Path, ...]
    names: tuple[str, ...]  # parameter columns (components of vectors as name[i])
    table: np.ndarray  # (n, len(names))

    def summary(self) -> str:
        """Mean, sd, 5% and 95% per parameter, as aligned text."""
        head = f"{'parameter':<44} {'mean':>12} {'sd':>11} {'5%':>12} {'95%':>12}"
        lines = [head, "-" * len(head)]
        for k, name in enumerate(self.names):
            col = self.table[:, k]
            q5, q95 = np.quantile(col, [0.05, 0.95])
            sd = col.std(ddof=1) if len(col) > 1 else 0.0
            lines.append(f"{name:<44} {col.mean():>12.5g} {sd:>11.3g} {q5:>12.5g} {q95:>12.5g}")
        return "\n".join(lines)


def sample(path: str | Path, n: int, seed: int = 0, outdir: str | Path = "samples", *,
           force: bool = False, simulate: bool = True) -> SampleResult:
    """Draw ``n`` scenes from the program at ``path`` into ``outdir``.

    Writes ``scene-0001/scene.phys`` (concrete), ``trajectory.csv`` and ``joints.csv``
    (simulated, <= 100 Hz) and, per camera, ``frames-CAM/`` (rendered PNG frames, their
    ``times.csv`` and ``render.mp4``) per draw, and ``parameters.csv`` (one row per scene).
    Refuses a non-empty ``outdir`` unless ``force``.
    """
    if n < 1:
        raise UsageError(f"-n must be at least 1, got {n}")
    path = Path(path)
    source = path.read_text(encoding="utf-8")
    scene = syntax.loads(source, filename=str(path), base_dir=path.parent)
    module = unroll_module(syntax.parse(source, str(path)))  # loops written out
    outdir = io.prepare_outdir(outdir, force=force)
    model = compile_scene(scene)
    draws = model.sample_prior(jax.random.PRNGKey(seed), n)
    units = {u.name: u.unit for u in scene.unknowns}
    params = parameter_values(module, draws, units)
    module = _for_scene_folder(module, path.parent, outdir, scene.duration)
    cameras = camera_renderers(model) if simulate else {}
    scenes = []
    for i in range(n):
        folder = outdir / f"scene-{i + 1:04d}"
        text = concrete_text(module, {k: (v[i], u) for k, (v, u) in params.items()}, source)
        io.write_text(folder / "scene.phys", text)
        if simulate:
            _simulate_into(folder, model, {k: v[i] for k, v in draws.items()}, cameras)
        scenes.append(folder / "scene.phys")
    names = columns({k: v[0] for k, (v, _) in params.items()})
    table = (np.concatenate([v.reshape(n, -1) for v, _ in params.values()], axis=1)
             if params else np.zeros((n, 0)))
    io.write_text(outdir / "parameters.csv", parameters_csv(names, table))
    return SampleResult(outdir, tuple(scenes), tuple(names), table)


def _simulate_into(folder: Path, model, values, cameras) -> None:
    """One draw's trajectory.csv, joints.csv (hinges and sliders) and camera frames in ``folder``."""
    scene, sim = model.scene, model.simulator
    moving = [not b.fixed and (b.shape is None or b.shape.kind != "plane") for b in
              (scene.body(name) for name in sim.body_names)]
    kinds = [scene.joint(name).kind for name in sim.joint_names]
    rollout = model.simulate(values)
    io.write_text(folder / "trajectory.csv", trajectory_csv(rollout, sim.body_names, moving))
    joints = joints_csv(rollout, sim.joint_names, kinds)
    if joints is not None:
        io.write_text(folder / "joints.csv", joints)
    for cam, (times, draw) in cameras.items():
        write_camera_frames(folder / frames_folder(cam), times, draw(rollout, values))


def _for_scene_folder(module, src_dir: Path, outdir: Path, duration: float):
    """``module`` as written one folder below ``outdir``: file names rebased, the duration
    fixed, and observations re-pointed at the scene's own generated data (positions and
    orientations in trajectory.csv, hinge/slider angles in joints.csv, camera images in
    frames-CAM/; others dropped)."""
    module = rebase_paths(module, src_dir, Path(outdir) / "scene-0000")
    decl = scene_decl(module)
    items = []
    for item in decl.items:
        if isinstance(item, A.ObserveItem):
            if item.quantity in ("position", "orientation"):
                item = dataclasses.replace(item, file="trajectory.csv", where=("body", item.target),
                                           rate=None, times=None)
            elif item.quantity == "angle":
                item = dataclasses.replace(item, file="joints.csv", where=("joint", item.target),
                                           rate=None, times=None)
            elif item.quantity == "image":
                folder = frames_folder(item.target)
                item = dataclasses.replace(item, file=f"{folder}/*.png", where=None, rate=None,
                                           times=f"{folder}/times.csv")
            else:
                continue
        items.append(item)
    items = ensure_duration(items, duration)
    return with_items(module, decl, items)
