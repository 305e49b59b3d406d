"""Rotations, quaternions (w, x, y, z) and 6D spatial algebra in world coordinates.

Spatial vectors are Plücker coordinates at the world origin: motion (omega, v_O) where v_O is
the velocity of the body point passing through the origin; force (n_O, f). Every helper is
differentiable everywhere (norms and normalisations are guarded at zero).
"""
from __future__ import annotations

import jax.numpy as jnp


def safe_norm(x, axis=-1, keepdims=False):
    """Euclidean norm whose gradient is 0 (not NaN) at the zero vector."""
    sq = jnp.sum(x * x, axis=axis, keepdims=keepdims)
    pos = sq > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1.0)), 0.0)


def normalize(x, axis=-1):
    """x / |x|, returning 0 for the zero vector with finite gradients."""
    n = safe_norm(x, axis=axis, keepdims=True)
    return x / jnp.where(n > 0, n, 1.0)


def mv(R, x):
    """R @ x over leading batch axes, unrolled into elementwise products and sums: XLA on CPU
    runs each tiny dot, and each reduction, as a kernel of its own; elementwise ops fuse."""
    return _sum(R[..., :, k] * x[..., None, k] for k in range(x.shape[-1]))


def mtv(R, x):
    """R^T @ x over leading batch axes (unrolled, see ``mv``)."""
    return _sum(R[..., k, :] * x[..., k, None] for k in range(x.shape[-1]))


def mm(A, B):
    """A @ B over leading batch axes (unrolled, see ``mv``)."""
    return _sum(A[..., :, k, None] * B[..., None, k, :] for k in range(A.shape[-1]))


def _sum(terms):
    terms = iter(terms)
    out = next(terms)
    for t in terms:
        out = out + t
    return out


def skew(a):
    """Cross-product matrix: skew(a) @ b == cross(a, b)."""
    z = jnp.zeros_like(a[..., 0])
    return jnp.stack([
        jnp.stack([z, -a[..., 2], a[..., 1]], -1),
        jnp.stack([a[..., 2], z, -a[..., 0]], -1),
        jnp.stack([-a[..., 1], a[..., 0], z], -1),
    ], -2)


def quat_mul(a, b):
    """Hamilton product a * b (rotate by b, then by a)."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return jnp.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], -1)


def quat_conj(q):
    return q * jnp.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def quat_to_mat(q):
    """Rotation matrix of a (not necessarily unit) quaternion; normalised first."""
    return unit_quat_to_mat(normalize(q))


def unit_quat_to_mat(q):
    """Rotation matrix of a unit quaternion (no renormalisation: one elementwise kernel)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return jnp.stack([
        jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        jnp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def quat_axis_angle(axis, angle):
    """Quaternion of a rotation by ``angle`` about the unit ``axis``."""
    half = 0.5 * angle
    return jnp.concatenate([jnp.cos(half)[..., None], jnp.sin(half)[..., None] * axis], -1)


def quat_exp(w):
    """Quaternion of the rotation vector ``w`` (angle |w| about w/|w|); smooth at w = 0."""
    th2 = jnp.sum(w * w, -1)
    small = th2 < 1e-12
    th = jnp.sqrt(jnp.where(small, 1.0, th2))
    # sin(th/2)/th and cos(th/2), with their Taylor series near zero
    s = jnp.where(small, 0.5 - th2 / 48.0, jnp.sin(0.5 * th) / th)
    c = jnp.where(small, 1.0 - th2 / 8.0, jnp.cos(0.5 * th))
    return jnp.concatenate([c[..., None], s[..., None] * w], -1)


def quat_integrate(q, w_local, h):
    """Advance orientation q by body-frame angular velocity ``w_local`` over time h; renormalised."""
    return normalize(quat_mul(q, quat_exp(w_local * h)))


def rotate(q, x):
    """Rotate vector x by quaternion q."""
    return mv(quat_to_mat(q), x)


def cross_motion(v, m):
    """Spatial cross product v x m of two motion vectors (6,) or (6, k)."""
    w, vo = v[:3], v[3:]
    if m.ndim == 1:
        return jnp.concatenate([jnp.cross(w, m[:3]), jnp.cross(w, m[3:]) + jnp.cross(vo, m[:3])])
    X = skew(w)
    return jnp.concatenate([X @ m[:3], X @ m[3:] + skew(vo) @ m[:3]], 0)


def cross_force(v, f):
    """Spatial cross product v x* f of a motion vector with a force vector (..., 6)."""
    w, vo = v[..., :3], v[..., 3:]
    return jnp.concatenate([jnp.cross(w, f[..., :3]) + jnp.cross(vo, f[..., 3:]),
                            jnp.cross(w, f[..., 3:])], -1)


def spatial_inertia(mass, inertia_com_world, com_world):
    """6x6 spatial inertia at the world origin of a body with mass, world-axes inertia about its
    COM, COM position; batched over leading axes."""
    C = skew(com_world)
    m = jnp.asarray(mass)[..., None, None]
    eye = jnp.broadcast_to(jnp.eye(3, dtype=C.dtype), C.shape)
    top = jnp.concatenate([inertia_com_world - m * mm(C, C), m * C], -1)
    bot = jnp.concatenate([-m * C, m * eye], -1)
    return jnp.concatenate([top, bot], -2)


def point_wrench(force, point, torque=None):
    """Spatial force at the origin of a world force applied at a world point (plus a free torque)."""
    n = jnp.cross(point, force)
    if torque is not None:
        n = n + torque
    return jnp.concatenate([n, force])
