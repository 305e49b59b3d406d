"""Markers: points fixed in a body's frame, read off the bodies' poses and velocities.

A marker at ``r`` (body frame) on a body at ``x`` with orientation ``R`` and velocities
``v``, ``w`` (world frame, of the body origin) is at ``p = x + R r`` and moves at
``v + w x (R r)``. Markers have no mass: they read the rollout, they do not change it.
"""
from __future__ import annotations

import jax.numpy as jnp

from ..expr import evaluate
from ..scene import Scene
from .spatial import quat_to_mat


def marker_tracks(scene: Scene, body_names, values, pos, quat, lin, ang):
    """Positions and velocities (T, M, 3) of the scene's markers, from the bodies' (T, B, ...)
    origin positions, quaternions and linear and angular velocities."""
    idx = jnp.asarray([body_names.index(m.body) for m in scene.markers], dtype=jnp.int32)
    r = jnp.stack([jnp.asarray(evaluate(m.position, values), dtype=pos.dtype)
                   for m in scene.markers])  # (M, 3) body frame
    arm = jnp.einsum("tmij,mj->tmi", quat_to_mat(quat[:, idx]), r)  # R r, world frame
    return pos[:, idx] + arm, lin[:, idx] + jnp.cross(ang[:, idx], arm)
