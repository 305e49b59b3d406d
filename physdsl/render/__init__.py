"""Differentiable rendering of physical scenes: primitives, MuJoCo-convention cameras, Lambert light.

``render(objects, light, camera, background, softness)`` is pure JAX; see docs/rendering.md.
"""
from .camera import pixel_rays, project, unproject
from .render import render, to_gray
from .types import (BOX, CAPSULE, CYLINDER, KIND_CODES, PLANE, SPHERE, Light, Objects,
                    RenderCamera, make_camera, make_light, make_objects)

__all__ = [
    "BOX", "CAPSULE", "CYLINDER", "KIND_CODES", "PLANE", "SPHERE", "Light", "Objects",
    "RenderCamera", "make_camera", "make_light", "make_objects", "pixel_rays", "project", "render", "to_gray",
    "unproject",
]
