"""Signed distance functions of the primitives in their local frame, selectable by a traced kind.

Points are given as separate coordinate arrays (x, y, z) of any common shape, so the renderer
evaluates many rays x objects as plain elementwise arrays (no trailing length-3 axes); ``sdf``
takes a (..., 3) point for everyone else.
"""
from __future__ import annotations

import jax.numpy as jnp

from .types import BOX, CAPSULE, CYLINDER, SPHERE

_EPS = 1e-24


def quat_to_matrix(q):
    """Rotation matrix (..., 3, 3) of quaternions (..., 4) as (w, x, y, z), normalised first."""
    q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return jnp.stack([jnp.stack(r, axis=-1) for r in rows], axis=-2)


def select(kind, options):
    """options[kind] for a traced integer array ``kind`` (elementwise, broadcasting)."""
    out = options[-1]
    for code in range(len(options) - 2, -1, -1):
        out = jnp.where(kind == code, options[code], out)
    return out


def sdf_parts(x, y, z, s0, s1, s2):
    """Signed distances (sphere, box, cylinder, capsule) of local points to primitives of size
    (s0, s1, s2): sphere (r, ., .), box half-extents, cylinder/capsule (r, half_length, .)."""
    sphere = jnp.sqrt(x * x + y * y + z * z + _EPS) - s0
    qx, qy, qz = jnp.abs(x) - s0, jnp.abs(y) - s1, jnp.abs(z) - s2
    mx, my, mz = jnp.maximum(qx, 0.0), jnp.maximum(qy, 0.0), jnp.maximum(qz, 0.0)
    box = jnp.sqrt(mx * mx + my * my + mz * mz + _EPS) + jnp.minimum(
        jnp.maximum(jnp.maximum(qx, qy), qz), 0.0)
    rho = jnp.sqrt(x * x + y * y + _EPS)
    dr, dz = rho - s0, jnp.abs(z) - s1
    mr, mz = jnp.maximum(dr, 0.0), jnp.maximum(dz, 0.0)
    cylinder = jnp.minimum(jnp.maximum(dr, dz), 0.0) + jnp.sqrt(mr * mr + mz * mz + _EPS)
    ez = z - jnp.clip(z, -s1, s1)
    capsule = jnp.sqrt(x * x + y * y + ez * ez + _EPS) - s0
    return sphere, box, cylinder, capsule


def sdf_xyz(kind, x, y, z, s0, s1, s2):
    """Signed distance of local points (x, y, z) to the convex primitive ``kind``."""
    return select(jnp.clip(kind, SPHERE, CAPSULE), sdf_parts(x, y, z, s0, s1, s2))


def sdf(kind, p, s):
    """Signed distance of local point(s) ``p`` (..., 3) to the primitive ``kind`` of size ``s``."""
    p, s = jnp.asarray(p), jnp.asarray(s)
    return sdf_xyz(kind, p[..., 0], p[..., 1], p[..., 2], s[..., 0], s[..., 1], s[..., 2])


assert (SPHERE, BOX, CYLINDER, CAPSULE) == (0, 1, 2, 3)
