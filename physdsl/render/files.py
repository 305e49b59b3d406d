"""Rendering a scene to files: frames as PNG, a video, posterior draws as a grid image."""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import jax
import numpy as np

from .. import io
from ..errors import UsageError
from ..observe.image import load_frames
from .scene import render_frames

DEFAULT_FPS = 30.0


def _cv2():
    import cv2

    return cv2


def to_uint8_bgr(image) -> np.ndarray:
    """An RGB float image in [0, 1] as 8-bit BGR (opencv's order)."""
    return np.round(np.clip(np.asarray(image), 0, 1)[:, :, ::-1] * 255).astype(np.uint8)


def write_png(path: Path, image) -> Path:
    with io.atomic_path(path) as tmp:
        ok, data = _cv2().imencode(".png", to_uint8_bgr(image))
        if not ok:
            raise UsageError(f"cannot encode '{path}' as PNG")
        tmp.write_bytes(data.tobytes())
    return path


def write_frames(images, folder: Path, fps: float) -> list[Path]:
    """``frame_0000.png``, ... and ``render.mp4`` (mp4v, if opencv can write it) in ``folder``."""
    paths = [write_png(folder / f"frame_{i:04d}.png", img) for i, img in enumerate(images)]
    h, w = np.asarray(images[0]).shape[:2]
    cv2 = _cv2()
    video = folder / "render.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (w, h))
    if writer.isOpened():
        for img in images:
            writer.write(to_uint8_bgr(img))
        writer.release()
        paths.append(video)
    return paths


def parse_params(items, model) -> dict:
    """``name=value`` or ``name=x,y,z`` settings of unknowns, checked against the model."""
    names = set(model.unknown_names)
    out = {}
    for item in items or ():
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise UsageError(f"--param '{item}' names no unknown of this scene" if sep else
                             f"--param '{item}' is not NAME=VALUE",
                             hint="unknowns: " + ", ".join(sorted(names)))
        try:
            value = np.array([float(v) for v in text.split(",")])
        except ValueError:
            raise UsageError(f"--param '{item}': '{text}' is not a number or a comma list") \
                from None
        shape = model.scene.unknown(name).shape
        if value.size != int(np.prod(shape)):
            raise UsageError(f"--param '{item}': {name} has shape {shape}")
        out[name] = value.reshape(shape)
    return out


def prior_medians(model, n: int = 501, seed: int = 0) -> dict:
    """Per-element medians of ``n`` joint prior draws of every unknown (discrete ones rounded)."""
    draws = model.sample_prior(jax.random.PRNGKey(seed), n)
    out = {}
    for u in model.unknowns:
        med = np.median(np.asarray(draws[u.name], dtype=float), axis=0)
        out[u.name] = np.round(med).astype(int) if u.discrete else med
    return out


def frame_times(model, camera: str, fps: float | None) -> np.ndarray:
    """Times to draw: the camera's observed frame times if it has an image observation and no
    ``fps`` is given, else every 1/fps over the simulated span."""
    obs = next((o for o in model.images if o.target == camera), None)
    if obs is not None and fps is None:
        return np.asarray(obs.times, dtype=float)
    end = float(model.simulator.times[-1])
    return np.arange(0.0, end + 1e-9, 1.0 / (fps or DEFAULT_FPS))


def pick_camera(scene, name: str | None) -> str:
    """The name of the scene's camera ``name`` (default: its first); a UsageError if none."""
    if not scene.cameras:
        raise UsageError(f"scene '{scene.name}' has no camera",
                         hint="add camera NAME { position ... look_at ... size ... }")
    names = [c.name for c in scene.cameras]
    if name is None:
        return names[0]
    if name not in names:
        raise UsageError(f"no camera called '{name}'", hint="cameras: " + ", ".join(names))
    return name


class Frames(NamedTuple):
    """Rendered frames: the camera's name, the times (F,) and the images (F, H, W, 3)."""

    camera: str
    times: np.ndarray
    images: np.ndarray


def frame_rate(times) -> float:
    """Frames per second of evenly spaced ``times`` (30 for a single frame)."""
    return float(1.0 / np.median(np.diff(times))) if len(times) > 1 else DEFAULT_FPS


def render_scene(model, values: dict, camera: str | None = None, fps: float | None = None
                 ) -> Frames:
    """The scene of ``model`` seen by ``camera`` over its frame times (``frame_times``), the
    unknowns at ``values`` and those not given at their prior medians."""
    cam = pick_camera(model.scene, camera)
    values = {**prior_medians(model), **values}
    times = frame_times(model, cam, fps)
    images = np.asarray(render_frames(model.scene, model.simulator, model.simulate(values),
                                      values, cam, times))
    return Frames(cam, times, images)


def posterior_images(model, post, camera: str | None, n: int, time: float | None
                     ) -> tuple[list[np.ndarray], float]:
    """(images, t): the camera's observed frame nearest ``t`` (if any) then ``n`` evenly spaced
    draws of the posterior ``post`` (name -> (chain, draw, ...)) rendered at ``t`` (default:
    the last observed frame, else 0)."""
    cam = pick_camera(model.scene, camera)
    missing = [u for u in model.unknown_names if u not in post]
    if missing:
        raise UsageError(f"the run has no draws of {', '.join(missing)}",
                         hint="give the run of this scene")
    obs = next((o for o in model.images if o.target == cam), None)
    t = time if time is not None else (float(obs.times[-1]) if obs is not None else 0.0)
    images = []
    if obs is not None:
        i = int(np.argmin(np.abs(np.asarray(obs.times) - t)))
        t = float(obs.times[i])
        images.append(load_frames([obs.frames[i]], times=[t])[1][0])
    flat = {u: np.asarray(post[u]).reshape((-1,) + np.asarray(post[u]).shape[2:])
            for u in model.unknown_names}
    total = next(iter(flat.values())).shape[0] if flat else 1
    for k in np.linspace(0, total - 1, min(n, total)).round().astype(int):
        values = {u: v[k] for u, v in flat.items()}
        images.append(np.asarray(render_frames(model.scene, model.simulator,
                                               model.simulate(values), values, cam,
                                               np.array([t])))[0])
    return images, t
