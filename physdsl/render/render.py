"""Differentiable ray-cast rendering of primitives with soft silhouettes and Lambert shading.

Per pixel, every object gives a coverage ``alpha = sigmoid(-distance_px / softness)`` from the
ray's signed distance to its surface (in pixels at that depth), a depth and a shaded colour
``color * (ambient * light.ambient + diffuse * light.diffuse * max(0, n . -light_dir))``
(MuJoCo's lighting without specular); layers are composited front to back over the background.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from .camera import pixel_rays, pixel_size
from .raycast import ray_convex, ray_object
from .types import PLANE, Camera, Light, Objects

DEFAULT_PLANE_EXTENT = 30.0  # m, half-size of planes (MuJoCo's corpus ground is 30 x 30)


def _composite(alpha, depth, color, background):
    """Front-to-back alpha compositing of per-object layers over the background."""
    order = jnp.argsort(depth)
    a = alpha[order]
    c = color[order]
    trans = jnp.cumprod(jnp.concatenate([jnp.ones(1), 1.0 - a[:-1]]))
    return jnp.sum((trans * a)[:, None] * c, axis=0) + jnp.prod(1.0 - a) * background


@partial(jax.jit, static_argnames=("shadows", "iterations"))
def render(objects: Objects, light: Light, camera: Camera, background, softness=0.5,
           shadows: bool = False, plane_extent=DEFAULT_PLANE_EXTENT, iterations: int = 24):
    """Image (H, W, 3) in [0, 1] of ``objects`` seen by ``camera``; row 0 is the top.

    ``softness`` is the silhouette edge width in pixels; ``shadows`` casts soft shadows of the
    convex objects onto every surface (planes cast none). Pure and jittable; vmap it over
    frames or posterior draws.
    """
    dirs, origin = pixel_rays(camera)
    pix = pixel_size(camera)
    to_light = -light.direction / jnp.linalg.norm(light.direction)
    background = jnp.broadcast_to(jnp.asarray(background, dtype=dirs.dtype), (3,))

    def per_ray(d):
        hit = jax.vmap(ray_object, in_axes=(None, None, 0, 0, 0, 0, None, None))
        sd, t, n = hit(origin, d, objects.kind, objects.pos, objects.quat, objects.size,
                       plane_extent, iterations)
        scale = jnp.maximum(t, 1e-3) * pix * softness
        alpha = jax.nn.sigmoid(-sd / scale) * objects.visible
        lambert = jnp.maximum(jnp.sum(n * to_light, axis=-1), 0.0)
        if shadows:
            lambert = lambert * _light_visibility(origin + t[:, None] * d + 1e-4 * n, to_light,
                                                  objects, scale, iterations)
        shade = objects.color * (objects.ambient[:, None] * light.ambient
                                 + (objects.diffuse * lambert)[:, None] * light.diffuse)
        return _composite(alpha, t, shade, background)

    image = jax.vmap(per_ray)(dirs.reshape(-1, 3)).reshape(dirs.shape)
    return jnp.clip(image, 0.0, 1.0)


def _light_visibility(points, to_light, objects: Objects, scale, iterations):
    """Fraction of light reaching each object's surface point (B,): soft occlusion by the others."""
    nobj = objects.kind.shape[0]

    def occlusion(p, i):
        sd, t, _ = jax.vmap(ray_convex, in_axes=(None, None, 0, 0, 0, 0, None))(
            p, to_light, objects.kind, objects.pos, objects.quat, objects.size, iterations)
        a = jax.nn.sigmoid(-sd / scale[i]) * objects.visible
        a = jnp.where((jnp.arange(nobj) == i) | (objects.kind == PLANE) | (t <= 2e-3), 0.0, a)
        return jnp.prod(1.0 - a)

    return jax.vmap(occlusion)(points, jnp.arange(nobj))


def to_gray(image):
    """Luma (ITU-R BT.601) of an RGB image (..., 3) -> (..., 1)."""
    return jnp.asarray(image) @ jnp.array([0.299, 0.587, 0.114])[:, None]
