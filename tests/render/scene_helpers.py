"""Scenes observed only through a camera: write truth frames with our renderer, load the scene."""
from pathlib import Path

import cv2
import numpy as np

from physdsl import syntax
from physdsl.compile import Model
from physdsl.render.scene import render_frames

TOSS = """
scene toss {{
  world {{ timestep: 10 ms  duration: {duration} s }}
  {params}
  ground floor {{ normal: (0, 0, 1)  point: (0, 0, 0) m  color: (0.6, 0.65, 0.6) }}
  body ball {{
    shape: sphere(radius: 8 cm)
    mass: 200 g
    position: (-0.4, 0, h0)
    velocity: (1.5, 0, v0)
    color: (0.9, 0.2, 0.1)
    collide: false  # in flight throughout (no contact solve to compile)
  }}
  camera cam {{ position: (0, -3.5, 1.0) m  look_at: (0, 0, 0.9) m  up: (0, 0, 1)  fov: 45 deg
               size: ({w}, {h})  background: (0.55, 0.7, 0.9) }}
  light {{ direction: (0.3, 0.4, -1)  ambient: 0.4  diffuse: 0.6 }}
  {observe}
}}
"""


def load(text: str, base: Path):
    return syntax.loads(text, "scene.phys", base)


def write_frames(scene, values, camera: str, times, folder: Path) -> np.ndarray:
    """Render the scene at ``values`` and write 8-bit PNG frames; returns the float frames."""
    model = Model(scene)
    rollout = model.simulate(values)
    images = np.asarray(render_frames(scene, model.simulator, rollout, values, camera, times))
    folder.mkdir(parents=True, exist_ok=True)
    for i, img in enumerate(images):
        cv2.imwrite(str(folder / f"frame_{i:04d}.png"),
                    np.round(img[:, :, ::-1] * 255).astype(np.uint8))
    return images
