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
from .raycast import cast, cast_from_points
from .types import PLANE, RenderCamera, Light, Objects

DEFAULT_PLANE_EXTENT = 30.0  # m, half-size of planes (MuJoCo's corpus ground is 30 x 30)


def _composite(alpha, depth, color, background):
    """Front-to-back alpha compositing of layers (P, B) over the background. One multi-operand
    ``lax.sort`` by depth (a fusion boundary: XLA would otherwise recompute the ray casts
    inside every consumer of the layers) and a cumulative transmittance."""
    _, a, r, g, b = jax.lax.sort((depth, alpha, color[..., 0], color[..., 1], color[..., 2]),
                                 dimension=-1, num_keys=1)
    trans = jnp.cumprod(jnp.concatenate([jnp.ones_like(a[..., :1]), 1.0 - a[..., :-1]], -1), -1)
    w = trans * a
    rgb = jnp.stack([jnp.sum(w * c, axis=-1) for c in (r, g, b)], axis=-1)
    return rgb + jnp.prod(1.0 - a, axis=-1)[..., None] * background


@partial(jax.jit, static_argnames=("shadows", "kinds"))
def render(objects: Objects, light: Light, camera: RenderCamera, background, softness=0.5,
           shadows: bool = False, plane_extent=DEFAULT_PLANE_EXTENT, kinds=None):
    """Image (H, W, 3) in [0, 1] of ``objects`` seen by ``camera``; row 0 is the top.

    ``softness`` is the silhouette edge width in pixels; ``shadows`` casts soft shadows of the
    convex objects onto every surface (planes cast none). ``kinds``: the objects' kind codes
    as a static tuple when they are known (only those primitives are computed, several times
    faster); without it ``objects.kind`` may be traced. Pure and jittable; vmap it over frames
    or posterior draws.
    """
    if kinds is not None:
        kinds = tuple(int(k) for k in kinds)
        order = sorted(range(len(kinds)), key=lambda i: kinds[i])
        objects = Objects(*(a[jnp.asarray(order, dtype=int)] for a in objects))
        kinds = tuple(kinds[i] for i in order)
    dirs, origin = pixel_rays(camera)
    rays = dirs.reshape(-1, 3)
    width = pixel_size(camera) * softness  # edge width in radians
    to_light = -light.direction / jnp.linalg.norm(light.direction)
    background = jnp.broadcast_to(jnp.asarray(background, dtype=dirs.dtype), (3,))
    ang, t, n = cast(origin, rays, objects, plane_extent, kinds)
    alpha = jax.nn.sigmoid(-ang / width) * objects.visible
    lambert = jnp.maximum(n @ to_light, 0.0)
    if shadows:
        points = origin + t[..., None] * rays[:, None] + 1e-4 * n
        lambert = lambert * _light_visibility(points, to_light, objects, t * width, kinds)
    shade = objects.color * (objects.ambient[:, None] * light.ambient
                             + (objects.diffuse * lambert)[..., None] * light.diffuse)
    image = _composite(alpha, t, shade, background).reshape(dirs.shape)
    return jnp.clip(image, 0.0, 1.0)


def _light_visibility(points, to_light, objects: Objects, scale, kinds):
    """Fraction of light reaching each surface point (P, B): soft occlusion by the other convex
    objects (edge width ``scale`` (P, B) in m at each point)."""
    sd, tc, front = cast_from_points(points, to_light, objects, kinds)  # (P, B, B)
    a = jax.nn.sigmoid(-sd / scale[..., None]) * objects.visible
    nobj = objects.kind.shape[0]
    self_or_plane = jnp.eye(nobj, dtype=bool) | (objects.kind == PLANE)[None, :]
    a = jnp.where(self_or_plane | ~front | (tc <= 2e-3), 0.0, a)
    return jnp.prod(1.0 - a, axis=-1)


def to_gray(image):
    """Luma (ITU-R BT.601) of an RGB image (..., 3) -> (..., 1)."""
    return jnp.asarray(image) @ jnp.array([0.299, 0.587, 0.114])[:, None]
