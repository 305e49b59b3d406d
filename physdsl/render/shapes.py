"""Signed distance functions of the primitives in their local frame, selectable by a traced kind.

All convex primitives (sphere, box, cylinder, capsule) share one code path: the renderer only
needs ``sdf(p)`` and a bounding radius, so a discrete (traced) shape is a ``select`` over kinds.
"""
from __future__ import annotations

import jax.numpy as jnp

from .types import BOX, CAPSULE, CYLINDER, SPHERE

_EPS = 1e-24


def _norm(x, axis=-1):
    """Euclidean norm with a finite gradient at zero."""
    return jnp.sqrt(jnp.sum(x * x, axis=axis) + _EPS)


def quat_to_matrix(q):
    """Rotation matrix (3, 3) of a quaternion (w, x, y, z), normalised first."""
    q = q / jnp.linalg.norm(q)
    w, x, y, z = q[0], q[1], q[2], q[3]
    return jnp.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def sdf_sphere(p, s):
    return _norm(p) - s[0]


def sdf_box(p, s):
    q = jnp.abs(p) - s
    return _norm(jnp.maximum(q, 0.0)) + jnp.minimum(jnp.max(q), 0.0)


def sdf_cylinder(p, s):
    d = jnp.stack([_norm(p[:2]) - s[0], jnp.abs(p[2]) - s[1]])
    return jnp.minimum(jnp.max(d), 0.0) + _norm(jnp.maximum(d, 0.0))


def sdf_capsule(p, s):
    q = p - jnp.array([0.0, 0.0, 1.0]) * jnp.clip(p[2], -s[1], s[1])
    return _norm(q) - s[0]


def sdf(kind, p, s):
    """Signed distance of local point ``p`` to the convex primitive ``kind`` of size ``s``."""
    vals = jnp.stack([sdf_sphere(p, s), sdf_box(p, s), sdf_cylinder(p, s), sdf_capsule(p, s)])
    return vals[jnp.clip(kind, SPHERE, CAPSULE)]


def bounding_radius(kind, s):
    """Radius of a sphere about the local origin that contains the primitive."""
    s = jnp.abs(s)
    vals = jnp.stack([s[0], _norm(s), _norm(s[:2]), s[0] + s[1]])
    return vals[jnp.clip(kind, SPHERE, CAPSULE)]


assert (SPHERE, BOX, CYLINDER, CAPSULE) == (0, 1, 2, 3)
