"""Camera geometry shared by the renderer and the tracker: rays per pixel and projection.

Pixel coordinates (u, v) are (column, row) with the centre of the top-left pixel at (0, 0),
the convention of image arrays and of opencv moments; row 0 is the top of the image.
"""
from __future__ import annotations

import jax.numpy as jnp

from .types import RenderCamera


def camera_frame(camera: RenderCamera):
    """Orthonormal (right, up, forward) world vectors of the camera (MuJoCo's look-at frame)."""
    fwd = camera.look_at - camera.position
    fwd = fwd / jnp.linalg.norm(fwd)
    right = jnp.cross(fwd, camera.up)
    right = right / jnp.linalg.norm(right)
    up = jnp.cross(right, fwd)
    return right, up, fwd


def focal_pixels(camera: RenderCamera):
    """Focal length in pixels from the vertical field of view."""
    return 0.5 * camera.height / jnp.tan(0.5 * camera.fovy)


def pixel_rays(camera: RenderCamera):
    """Unit ray directions (H, W, 3) through pixel centres, and the camera origin (3,)."""
    right, up, fwd = camera_frame(camera)
    f = focal_pixels(camera)
    cols = jnp.arange(camera.width) + 0.5 - 0.5 * camera.width
    rows = 0.5 * camera.height - (jnp.arange(camera.height) + 0.5)
    x = cols[None, :, None] / f
    y = rows[:, None, None] / f
    d = fwd + x * right + y * up
    return d / jnp.linalg.norm(d, axis=-1, keepdims=True), camera.position


def project(camera: RenderCamera, points):
    """Pixel coordinates (..., 2) as (u, v) of world points (..., 3), and their depth (...,)."""
    right, up, fwd = camera_frame(camera)
    rel = jnp.asarray(points) - camera.position
    z = rel @ fwd
    f = focal_pixels(camera)
    u = 0.5 * camera.width - 0.5 + f * (rel @ right) / z
    v = 0.5 * camera.height - 0.5 - f * (rel @ up) / z
    return jnp.stack([u, v], axis=-1), z


def unproject(camera: RenderCamera, uv, depth):
    """World points (..., 3) at camera depth ``depth`` (along the optical axis) seen at pixel ``uv``."""
    right, up, fwd = camera_frame(camera)
    uv = jnp.asarray(uv)
    f = focal_pixels(camera)
    x = (uv[..., 0] - 0.5 * camera.width + 0.5) / f
    y = (0.5 * camera.height - 0.5 - uv[..., 1]) / f
    depth = jnp.asarray(depth)[..., None]
    return camera.position + depth * (fwd + x[..., None] * right + y[..., None] * up)


def pixel_size(camera: RenderCamera):
    """Size of one pixel at unit distance (radians per pixel near the centre)."""
    return 2.0 * jnp.tan(0.5 * camera.fovy) / camera.height
