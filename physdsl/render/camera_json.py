"""Read a camera description (``camera.json`` of the corpus, MuJoCo-rendered frames) into
renderer inputs: RenderCamera, Light, background and ground colours, per-object colours."""
from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import DataError
from .types import RenderCamera, Light, make_camera, make_light


class CameraSpec(NamedTuple):
    camera: RenderCamera
    light: Light
    background: np.ndarray  # (3,)
    ground: np.ndarray | None  # (3,) colour of the ground plane, if the file names one
    colors: dict  # object name -> (3,) RGB
    frame_rate: float | None


def load_camera_json(path: str | Path) -> CameraSpec:
    """Parse ``camera.json`` (position, look_at, up, fovy_deg, width, height, light, colours)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError("camera file not found", path) from None
    except (OSError, ValueError) as ex:
        raise DataError(f"cannot read camera file: {ex}", path) from None
    try:
        size = data.get("size") or (data["width"], data["height"])
        camera = make_camera(data["position"], data["look_at"], data.get("up", (0, 0, 1)),
                             np.deg2rad(float(data["fovy_deg"])), int(size[0]), int(size[1]))
        light_d = data.get("light", {})
        light = make_light(light_d.get("direction", (0.0, 0.0, -1.0)),
                           light_d.get("ambient", 0.35), light_d.get("diffuse", 0.65))
        background = np.asarray(data.get("background_rgb", (0.0, 0.0, 0.0)), dtype=float)
        ground = data.get("ground_rgb")
        colors = {k: np.asarray(v, dtype=float) for k, v in data.get("object_rgb", {}).items()}
        rate = data.get("frame_rate_hz")
    except (KeyError, TypeError, ValueError, IndexError) as ex:
        raise DataError(f"camera file lacks or mangles a field: {ex}", path,
                        hint="needs position, look_at, fovy_deg, width and height") from None
    return CameraSpec(camera, light, background,
                      None if ground is None else np.asarray(ground, dtype=float), colors,
                      None if rate is None else float(rate))
