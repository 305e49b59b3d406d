"""Small NaN-safe geometry helpers for contact detection (pure JAX, float64-friendly).

Every norm and division is guarded so that gradients stay finite at degenerate
configurations (coincident centres, a cylinder standing exactly upright, ...).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

_TINY = 1e-24  # squared length below which a vector counts as zero


def safe_norm(x, axis=-1):
    """Euclidean norm with a finite gradient at zero (gradient 0 there)."""
    n2 = jnp.sum(x * x, axis=axis)
    pos = n2 > _TINY
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, n2, 1.0)), 0.0)


def safe_normalize(x, fallback):
    """x / |x|, or ``fallback`` (a unit vector) where |x| is zero."""
    n = safe_norm(x)
    pos = (n > 1e-12)[..., None]
    return jnp.where(pos, x / jnp.where(pos, n[..., None], 1.0), fallback)


def quat_to_matrix(q):
    """Rotation matrix (body -> world) of quaternion (w, x, y, z); normalised first."""
    q = safe_normalize(q, jnp.array([1.0, 0.0, 0.0, 0.0], dtype=jnp.result_type(q, float)))
    w, x, y, z = q[0], q[1], q[2], q[3]
    return jnp.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def box_closest(p, half):
    """Signed distance of local point p to a box, outward normal and closest surface point.

    Outside: the clamped point; inside: the nearest face (negative distance).
    """
    q = jnp.clip(p, -half, half)
    d = p - q
    outside = jnp.any(jnp.abs(p) > half)
    depth = half - jnp.abs(p)
    k = jnp.argmin(depth)
    sign = jnp.where(p[k] >= 0, 1.0, -1.0)
    e_k = jax.nn.one_hot(k, 3, dtype=p.dtype)
    n_in = sign * e_k
    s_in = jnp.where(e_k > 0, sign * half, p)
    n_out = safe_normalize(d, n_in)
    dist = jnp.where(outside, safe_norm(d), -depth[k])
    return dist, jnp.where(outside, n_out, n_in), jnp.where(outside, q, s_in)


def cylinder_closest(p, radius, half_length):
    """Signed distance of local point p to a solid cylinder along local z, normal, surface point."""
    rho = safe_norm(p[:2])
    u = safe_normalize(p[:2], jnp.array([1.0, 0.0], dtype=p.dtype))
    q = jnp.concatenate([u * jnp.minimum(rho, radius), jnp.clip(p[2:], -half_length, half_length)])
    d = p - q
    outside = (rho > radius) | (jnp.abs(p[2]) > half_length)
    side_depth = radius - rho
    cap_depth = half_length - jnp.abs(p[2])
    sign = jnp.where(p[2] >= 0, 1.0, -1.0)
    side = side_depth < cap_depth
    zero = jnp.zeros((), p.dtype)
    n_in = jnp.where(side, jnp.concatenate([u, zero[None]]), jnp.array([0.0, 0.0, 1.0]) * sign)
    s_in = jnp.where(side, jnp.concatenate([u * radius, p[2:]]),
                     jnp.concatenate([p[:2], (sign * half_length)[None]]))
    n_out = safe_normalize(d, n_in)
    dist = jnp.where(outside, safe_norm(d), -jnp.minimum(side_depth, cap_depth))
    return dist, jnp.where(outside, n_out, n_in), jnp.where(outside, q, s_in)


def segment_closest_param(a, axis, half_length, p):
    """Parameter t in [-L, L] of the point a + t axis nearest to p."""
    return jnp.clip(jnp.dot(p - a, axis), -half_length, half_length)


def segments_closest(a, u, la, b, v, lb):
    """Closest points of segments a + s u (|s| <= la) and b + t v (|t| <= lb); u, v unit.

    Ericson's clamped solution; parallel segments take the middle of the overlap on A.
    """
    r = a - b
    c = jnp.dot(u, v)
    d1, d2 = jnp.dot(u, r), jnp.dot(v, r)
    den = 1.0 - c * c
    parallel = den < 1e-12
    s_free = jnp.where(parallel, 0.0, (c * d2 - d1) / jnp.where(parallel, 1.0, den))
    # Parallel: centre of the overlap of A with B's projection onto A's line.
    lo = jnp.maximum(-la, jnp.minimum(-d1 - c * lb, -d1 + c * lb))
    hi = jnp.minimum(la, jnp.maximum(-d1 - c * lb, -d1 + c * lb))
    s_par = jnp.clip(0.5 * (lo + hi), -la, la)
    s = jnp.clip(jnp.where(parallel, s_par, s_free), -la, la)
    t = jnp.clip(d2 + c * s, -lb, lb)
    s = jnp.clip(c * t - d1, -la, la)
    return a + s * u, b + t * v


def convex_line_min(f, lo, hi, iterations=40):
    """argmin of a convex scalar f on [lo, hi] by golden-section search (no gradient: the
    minimum's derivative comes from f at the argmin, by the envelope theorem)."""
    g = 0.5 * (jnp.sqrt(5.0) - 1.0)

    def body(_, ab):
        a, b = ab
        x1, x2 = b - g * (b - a), a + g * (b - a)
        left = f(x1) < f(x2)
        return jnp.where(left, a, x1), jnp.where(left, x2, b)

    a, b = jax.lax.fori_loop(0, iterations, body, (lo, hi))
    return jax.lax.stop_gradient(0.5 * (a + b))
