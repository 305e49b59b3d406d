"""Rendering a scene to files: frames as PNG, a video, posterior draws as a grid image."""
from __future__ import annotations

from pathlib import Path

import jax
import numpy as np

from ..errors import UsageError
from .. import io

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
    if not scene.cameras:
        raise UsageError(f"scene '{scene.name}' has no camera",
                         hint="add camera NAME { position ... look_at ... size ... }")
    names = [c.name for c in scene.cameras]
    if name is None:
        return names[0]
    if name not in names:
        raise UsageError(f"no camera called '{name}'", hint="cameras: " + ", ".join(names))
    return name
