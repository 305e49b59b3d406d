"""Ray against one object: signed distance of the ray to the surface, hit depth, surface normal.

For convex primitives the ray's distance to the surface is ``min_t sdf(o + t d)`` (convex in t,
found by golden-section search); it is negative when the ray enters the object, which gives
soft silhouettes with gradients at the edges. The search runs without gradients; gradients
come from the envelope theorem (value at the minimiser) and one Newton step at the hit.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from .shapes import bounding_radius, quat_to_matrix, sdf
from .types import PLANE

NEAR = 1e-3  # m: nothing is drawn closer to the ray origin
_GOLD = 0.5 * (jnp.sqrt(5.0) - 1.0)


def _golden_min(f, a, b, n):
    """Minimiser of a convex f on [a, b] by ``n`` golden-section steps (no gradients)."""
    c = b - _GOLD * (b - a)
    d = a + _GOLD * (b - a)

    def step(_, s):
        a, b, c, d, fc, fd = s
        left = fc < fd
        a2 = jnp.where(left, a, c)
        b2 = jnp.where(left, d, b)
        c2 = jnp.where(left, b2 - _GOLD * (b2 - a2), d)
        d2 = jnp.where(left, c, a2 + _GOLD * (b2 - a2))
        fnew = f(jnp.where(left, c2, d2))
        fc2 = jnp.where(left, fnew, fd)
        fd2 = jnp.where(left, fc, fnew)
        return a2, b2, c2, d2, fc2, fd2

    a, b, c, d, fc, fd = jax.lax.fori_loop(0, n, step, (a, b, c, d, f(c), f(d)))
    return jnp.where(fc < fd, c, d)


def _bisect_root(f, lo, hi, n):
    """Root of f with f(lo) > 0 >= f(hi) by ``n`` bisection steps (no gradients)."""

    def step(_, s):
        lo, hi = s
        mid = 0.5 * (lo + hi)
        out = f(mid) > 0
        return jnp.where(out, mid, lo), jnp.where(out, hi, mid)

    lo, hi = jax.lax.fori_loop(0, n, step, (lo, hi))
    return 0.5 * (lo + hi)


def ray_convex(o, d, kind, pos, quat, size, iterations=24):
    """(signed ray distance, depth t, world normal) of ray o + t d (d unit) and a convex primitive."""
    rot = quat_to_matrix(quat)
    ol = rot.T @ (o - pos)
    dl = rot.T @ d

    def f(t, ol=ol, dl=dl, size=size):
        return sdf(kind, ol + t * dl, size)

    fs = jax.lax.stop_gradient
    o_s, d_s, s_s = fs(ol), fs(dl), fs(size)

    def f_s(t):
        return sdf(kind, o_s + t * d_s, s_s)

    radius = bounding_radius(kind, s_s)
    tc = -jnp.dot(o_s, d_s)
    half = 1.1 * radius + 1e-6
    t0 = jnp.maximum(tc - half, NEAR)
    t1 = jnp.maximum(tc + half, NEAR)
    t_min = _golden_min(f_s, t0, t1, iterations)
    sd = f(t_min)  # envelope theorem: gradient of the minimum is the partial at the minimiser
    hit = f_s(t_min) < 0
    t_root = _bisect_root(f_s, t0, jnp.where(hit, t_min, t1), iterations)
    grad_p = jax.grad(lambda p: sdf(kind, p, s_s))
    slope = fs(jnp.dot(grad_p(o_s + t_root * d_s), d_s))
    slope = jnp.where(slope < -1e-9, slope, -1e-9)
    t_hit = t_root - f(t_root) / slope  # one Newton step: exact first-order gradients of depth
    # a missed ray's depth is the object centre's along the ray: differentiable, and it only
    # sets the silhouette's edge width (alpha is 1/2 at the edge whatever the width)
    tc = -jnp.dot(ol, dl)
    t = jnp.where(hit, t_hit, jnp.maximum(tc, NEAR))
    # a missed ray is shaded at its closest point, moved with the centre's depth for gradients
    # (exact for spheres, first-order otherwise; it only colours the soft fringe)
    t_close = t_min + tc - fs(tc)
    g = jax.grad(lambda p: sdf(kind, p, size))(ol + jnp.where(hit, t_hit, t_close) * dl)
    n_local = g / jnp.sqrt(jnp.sum(g * g) + 1e-24)
    return sd, t, rot @ n_local


def _plane_axes(n):
    """Two unit vectors spanning the plane with normal n (x/y for a z normal, like MuJoCo)."""
    ref = jnp.where(jnp.abs(n[0]) < 0.9, jnp.array([1.0, 0.0, 0.0]), jnp.array([0.0, 1.0, 0.0]))
    e1 = jnp.cross(n, ref)
    e1 = e1 / jnp.linalg.norm(e1)
    return e1, jnp.cross(n, e1)


def ray_plane(o, d, pos, normal, extent):
    """(signed ray distance, depth, normal) for a square plane of half-size ``extent`` seen from
    the side its normal points to. The distance is the angle between the ray and the square's
    projected outline (planes through the eye and each edge) times the depth, so the horizon
    edge is soft by exactly ``softness`` pixels however grazing the view."""
    n = normal / jnp.linalg.norm(normal)
    denom = jnp.dot(d, n)
    facing = (denom < -1e-12) & (jnp.dot(o - pos, n) > 0)
    t = jnp.dot(pos - o, n) / jnp.where(facing, denom, -1.0)
    e1, e2 = _plane_axes(n)
    signs = jnp.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    corners = pos + extent * (signs[:, :1] * e1 + signs[:, 1:] * e2) - o
    m = jnp.cross(corners, jnp.roll(corners, -1, axis=0))
    m = m / jnp.linalg.norm(m, axis=1, keepdims=True)
    m = m * -jnp.sign(m @ (pos - o))[:, None]  # outward: the centre is inside
    angle = jnp.max(m @ d)
    ok = facing & (t > NEAR)
    depth = jnp.where(ok, t, 1e6)
    return jnp.where(jnp.dot(o - pos, n) > 0, angle * depth, 1e6), depth, n


def ray_object(o, d, kind, pos, quat, size, extent, iterations=24):
    """Ray against an object of any kind (a traced kind evaluates both paths and selects)."""
    sd_c, t_c, n_c = ray_convex(o, d, kind, pos, quat, size, iterations)
    sd_p, t_p, n_p = ray_plane(o, d, pos, size, extent)
    plane = kind == PLANE
    return (jnp.where(plane, sd_p, sd_c), jnp.where(plane, t_p, t_c),
            jnp.where(plane, n_p, n_c))
