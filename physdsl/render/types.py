"""Inputs of the renderer: objects, light and camera as pytrees of arrays.

Objects and Light are NamedTuples (every field a leaf, so they vmap over frames and draws);
RenderCamera (named apart from the scene's ``scene.Camera`` declaration) is a dataclass pytree
whose ``width``/``height`` are static (they fix the image shape).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import jax
import jax.numpy as jnp

SPHERE, BOX, CYLINDER, CAPSULE, PLANE = 0, 1, 2, 3, 4
KIND_CODES = {"sphere": SPHERE, "box": BOX, "cylinder": CYLINDER, "capsule": CAPSULE,
              "plane": PLANE}
KIND_NAMES = {v: k for k, v in KIND_CODES.items()}


class Objects(NamedTuple):
    """B objects. size: sphere (r, 0, 0); box half-extents; cylinder/capsule (r, half_length, 0)
    along local z; plane: unit normal (the surface passes through ``pos``)."""

    kind: jax.Array  # (B,) int codes, may be traced
    pos: jax.Array  # (B, 3) world position
    quat: jax.Array  # (B, 4) w, x, y, z body -> world
    size: jax.Array  # (B, 3)
    color: jax.Array  # (B, 3) RGB in [0, 1]
    ambient: jax.Array  # (B,) material ambient factor
    diffuse: jax.Array  # (B,) material diffuse factor
    visible: jax.Array  # (B,) 1 shown, 0 hidden (may be fractional)


class Light(NamedTuple):
    """A directional light, MuJoCo style: ``direction`` is where the light travels (any length)."""

    direction: jax.Array  # (3,)
    ambient: jax.Array  # (3,) RGB
    diffuse: jax.Array  # (3,) RGB


@dataclass(frozen=True)
class RenderCamera:
    """Pinhole camera in MuJoCo's convention: at ``position`` looking at ``look_at``;
    ``fovy`` is the vertical field of view in radians; principal point at the image centre."""

    position: jax.Array  # (3,)
    look_at: jax.Array  # (3,)
    up: jax.Array  # (3,)
    fovy: jax.Array  # scalar, rad
    width: int = field(default=64, metadata={"static": True})
    height: int = field(default=64, metadata={"static": True})


jax.tree_util.register_dataclass(
    RenderCamera, data_fields=["position", "look_at", "up", "fovy"],
    meta_fields=["width", "height"])


def make_objects(kind, pos, size, color, quat=None, ambient=None, diffuse=None, visible=None
                 ) -> Objects:
    """Objects from per-object lists, filling identity orientation and MuJoCo's material (1, 1)."""
    pos = jnp.atleast_2d(jnp.asarray(pos, dtype=float))
    n = pos.shape[0]
    kind = jnp.asarray([KIND_CODES[k] if isinstance(k, str) else k
                        for k in (kind if isinstance(kind, (list, tuple)) else [kind])]
                       if not hasattr(kind, "shape") else kind, dtype=jnp.int32).reshape(n)
    quat = jnp.tile(jnp.array([1.0, 0, 0, 0]), (n, 1)) if quat is None else \
        jnp.atleast_2d(jnp.asarray(quat, dtype=float))
    ones = jnp.ones(n)
    return Objects(
        kind=kind, pos=pos, quat=quat,
        size=jnp.atleast_2d(jnp.asarray(size, dtype=float)),
        color=jnp.atleast_2d(jnp.asarray(color, dtype=float)),
        ambient=ones if ambient is None else jnp.asarray(ambient, dtype=float).reshape(n),
        diffuse=ones if diffuse is None else jnp.asarray(diffuse, dtype=float).reshape(n),
        visible=ones if visible is None else jnp.asarray(visible, dtype=float).reshape(n),
    )


def make_light(direction=(0.0, 0.0, -1.0), ambient=0.35, diffuse=0.65) -> Light:
    """A Light with scalar or RGB ambient/diffuse intensities."""
    amb = jnp.broadcast_to(jnp.asarray(ambient, dtype=float), (3,))
    dif = jnp.broadcast_to(jnp.asarray(diffuse, dtype=float), (3,))
    return Light(jnp.asarray(direction, dtype=float), amb, dif)


def make_camera(position, look_at, up=(0.0, 0.0, 1.0), fovy=0.7, width=64, height=64
                ) -> RenderCamera:
    """A RenderCamera from plain numbers (fovy in radians)."""
    return RenderCamera(jnp.asarray(position, dtype=float), jnp.asarray(look_at, dtype=float),
                  jnp.asarray(up, dtype=float), jnp.asarray(fovy, dtype=float),
                  int(width), int(height))
