"""Rays against objects in closed form: signed ray distance, hit depth, surface normal.

Every convex primitive gives, in its body frame, the ray's entry depth ``t_in`` (quadratic for
sphere, cylinder side and capsule ends; slabs for box and cylinder caps) and one point of
closest approach ``t_c``: exact for sphere and capsule (ray to centre / to segment), and for
box and cylinder the middle of the (possibly empty) interval [last entry, first exit]. The SDF
evaluated once at ``t_c`` is the ray's signed distance: negative exactly when the ray enters
the object (the point lies on the chord), positive otherwise, and continuous across the
silhouette, so soft edges have gradients without marching. A traced kind computes every
primitive and selects one.

Vectors are tuples of coordinate arrays (x, y, z) of a common broadcast shape (rays x
objects), so everything is elementwise and vectorised.
"""
from __future__ import annotations

import jax.numpy as jnp

from .shapes import quat_to_matrix, sdf_parts, select
from .types import CAPSULE, PLANE, SPHERE, Objects

NEAR = 1e-3  # m: nothing is drawn closer to the ray origin
_TINY = 1e-12
_FAR = 1e6


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _axpy(t, d, o):
    """o + t d."""
    return tuple(oi + t * di for oi, di in zip(o, d))


def _unit(v):
    n = jnp.sqrt(_dot(v, v) + 1e-24)
    return tuple(vi / n for vi in v)


def _sqrt_pos(x):
    """sqrt(max(x, 0)) with a finite gradient everywhere."""
    pos = x > _TINY
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def _safe_inv(x):
    """1 / x with |x| kept above a tiny floor (sign kept; zero counts as positive)."""
    return 1.0 / jnp.where(jnp.abs(x) < _TINY, jnp.where(x < 0, -_TINY, _TINY), x)


def _sphere(o, d, r):
    """(t_closest, t_in, t_out, local normal) of a sphere of radius r at the origin."""
    tc = -_dot(o, d)
    p = _axpy(tc, d, o)
    half = _sqrt_pos(r * r - _dot(p, p))
    t_in = tc - half
    return (tc,), t_in, tc + half, _unit(_axpy(t_in, d, o))


def _slab(o, d, half):
    """Entry and exit depths of the ray through -half <= p <= half along one axis."""
    inv = _safe_inv(d)
    t1, t2 = (-half - o) * inv, (half - o) * inv
    return jnp.minimum(t1, t2), jnp.maximum(t1, t2)


def _box(o, d, s):
    """Box of half-extents s: slab interval; normal of the face entered last."""
    (lx, hx), (ly, hy), (lz, hz) = (_slab(o[i], d[i], s[i]) for i in range(3))
    t_in = jnp.maximum(jnp.maximum(lx, ly), lz)
    t_out = jnp.minimum(jnp.minimum(hx, hy), hz)
    on_x = (lx >= ly) & (lx >= lz)
    on_y = ~on_x & (ly >= lz)
    on_z = ~on_x & ~on_y
    zero = jnp.zeros_like(t_in)
    normal = tuple(jnp.where(on, -jnp.sign(di), zero) for on, di in zip((on_x, on_y, on_z), d))
    return (0.5 * (t_in + t_out), -_dot(o, d)), t_in, t_out, normal


def _radial(o, d, r):
    """Interval of the ray inside the infinite cylinder x^2 + y^2 <= r^2 (when it misses:
    zero width at the closest approach to the axis)."""
    a = jnp.maximum(d[0] ** 2 + d[1] ** 2, _TINY)
    b = o[0] * d[0] + o[1] * d[1]
    c = o[0] ** 2 + o[1] ** 2 - r * r
    tc = -b / a
    half = _sqrt_pos(b * b - a * c) / a
    return tc - half, tc + half, tc


def _cylinder(o, d, s):
    """Cylinder of radius s[0], half-length s[1] along z: side interval cut by the z slab."""
    lo_r, hi_r, t_axis = _radial(o, d, s[0])
    lo_z, hi_z = _slab(o[2], d[2], s[1])
    t_in, t_out = jnp.maximum(lo_r, lo_z), jnp.minimum(hi_r, hi_z)
    p = _axpy(t_in, d, o)
    cap = lo_z > lo_r
    zero = jnp.zeros_like(t_in)
    radial = _unit((p[0], p[1], zero))
    normal = (jnp.where(cap, zero, radial[0]), jnp.where(cap, zero, radial[1]),
              jnp.where(cap, -jnp.sign(d[2]), zero))
    cands = (0.5 * (t_in + t_out), -_dot(o, d), jnp.clip(t_axis, lo_z, hi_z))
    return cands, t_in, t_out, normal


def _capsule(o, d, s):
    """Capsule: the segment (0, 0, +-s[1]) swept by radius s[0]. The ray's closest approach to
    the segment is exact (clamped line-line); the entry is the first of side and end spheres."""
    r, h = s[0], s[1]
    odl = _dot(o, d)
    seg = jnp.clip((o[2] - odl * d[2]) / jnp.maximum(1.0 - d[2] ** 2, _TINY), -h, h)
    tc = -odl + seg * d[2]
    lo_r, hi_r, _ = _radial(o, d, r)
    side = (hi_r > lo_r) & (jnp.abs(o[2] + lo_r * d[2]) <= h)
    t_in = jnp.where(side, lo_r, _FAR)
    t_out = hi_r
    for z in (-h, h):
        _, e_in, e_out, _ = _sphere((o[0], o[1], o[2] - z), d, r)
        t_in = jnp.minimum(t_in, jnp.where(e_out > e_in, e_in, _FAR))
        t_out = jnp.maximum(t_out, e_out)
    p = _axpy(jnp.where(t_in < _FAR, t_in, tc), d, o)
    normal = _unit((p[0], p[1], p[2] - jnp.clip(p[2], -h, h)))
    return (tc,), t_in, t_out, normal


_PRIMITIVES = (_sphere, _box, _cylinder, _capsule)


def convex_hits(o, d, kind, size):
    """Local-frame ray o + t d (unit d) against convex primitives of kind ``kind``: a Python
    int computes that primitive only, an array (possibly traced) computes all and selects.

    Returns (signed distance in m, closest-approach distance along the ray (>= NEAR), depth to
    draw at, local normal, in front of the origin), all of the broadcast shape of the inputs.
    """
    s = (size[..., 0], size[..., 1], size[..., 2])
    if isinstance(kind, int):
        cands, t_in, t_out, normal = _PRIMITIVES[kind](o, d, s[0] if kind == SPHERE else s)

        def field(t):
            return sdf_parts(*_axpy(t, d, o), *s)[kind]
    else:
        parts = [f(o, d, s[0] if f is _sphere else s) for f in _PRIMITIVES]
        k = jnp.clip(kind, SPHERE, CAPSULE)
        n_c = max(len(p[0]) for p in parts)
        cands = tuple(select(k, [p[0][min(i, len(p[0]) - 1)] for p in parts])
                      for i in range(n_c))
        t_in, t_out = (select(k, [p[i] for p in parts]) for i in (1, 2))
        normal = tuple(select(k, [p[3][j] for p in parts]) for j in range(3))

        def field(t):
            return select(k, sdf_parts(*_axpy(t, d, o), *s))
    # the SDF at each candidate point; all are >= the ray's true distance, so keep the least
    # (sphere, capsule: one exact point; box, cylinder: chord middle, closest approach to the
    # centre, and for the cylinder to its axis within the caps' slab)
    tc, sd = cands[0], field(cands[0])
    for t in cands[1:]:
        v = field(t)
        closer = v < sd
        tc, sd = jnp.where(closer, t, tc), jnp.minimum(sd, v)
    hit = sd < 0
    depth = jnp.maximum(jnp.where(hit, t_in, tc), NEAR)
    front = jnp.where(hit, t_out, tc) > NEAR
    return sd, jnp.maximum(tc, NEAR), depth, normal, front


def _to_local(rot, v):
    """Components of world vectors v (..., B, 3) in the frames rot (B, 3, 3): rot^T v."""
    return tuple(jnp.sum(rot[..., :, k] * v, axis=-1) for k in range(3))


def _to_world(rot, n):
    """World vectors (..., B, 3) of local components n in the frames rot (B, 3, 3)."""
    return sum(rot[..., :, k] * n[k][..., None] for k in range(3))


def _plane_axes(n):
    """Two unit vectors spanning the plane with normal n (x/y for a z normal, like MuJoCo)."""
    ref = jnp.where(jnp.abs(n[..., :1]) < 0.9, jnp.array([1.0, 0.0, 0.0]),
                    jnp.array([0.0, 1.0, 0.0]))
    e1 = jnp.cross(n, ref)
    e1 = e1 / jnp.linalg.norm(e1, axis=-1, keepdims=True)
    return e1, jnp.cross(n, e1)


def _plane_hits(origin, dirs, pos, normal, extent):
    """(angular signed distance, depth, unit normal) of rays (P, 3) from ``origin`` against
    squares (B) of half-size ``extent`` through ``pos`` seen from the side their normal points
    to. The distance is the angle between the ray and the square's projected outline (planes
    through the eye and each edge), so the horizon is soft by ``softness`` pixels however
    grazing the view."""
    n = normal / jnp.linalg.norm(normal, axis=-1, keepdims=True)  # (B, 3)
    height = jnp.sum((origin - pos) * n, axis=-1)  # (B,)
    above = height > 0
    e1, e2 = _plane_axes(n)
    signs = jnp.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    corners = (pos[:, None] + extent * (signs[None, :, :1] * e1[:, None]
                                        + signs[None, :, 1:] * e2[:, None]) - origin)
    m = jnp.cross(corners, jnp.roll(corners, -1, axis=1))  # (B, 4, 3)
    m = m / jnp.linalg.norm(m, axis=-1, keepdims=True)
    m = m * -jnp.sign(jnp.einsum("bcj,bj->bc", m, pos - origin))[..., None]  # centre inside
    angle = jnp.max(jnp.einsum("pj,bcj->pbc", dirs, m), axis=-1)  # (P, B)
    denom = dirs @ n.T  # (P, B)
    facing = (denom < -1e-12) & above
    t = -height / jnp.where(facing, denom, -1.0)
    depth = jnp.where(facing & (t > NEAR), t, _FAR)
    return jnp.where(above, angle, 1.0), depth, jnp.broadcast_to(n, denom.shape + (3,))


def _groups(kinds, n):
    """Contiguous runs [(kind, start, stop)] of static ``kinds``; one traced group without."""
    if kinds is None:
        return [(None, 0, n)]
    runs, start = [], 0
    for i in range(1, n + 1):
        if i == n or kinds[i] != kinds[start]:
            runs.append((int(kinds[start]), start, i))
            start = i
    return runs


def _take(objects: Objects, start, stop) -> Objects:
    return Objects(*(a[start:stop] for a in objects))


def cast(origin, dirs, objects: Objects, extent, kinds=None):
    """Rays from ``origin`` (3,) along unit ``dirs`` (P, 3) against every object (B).

    Returns (angular signed distance (P, B) in rad: negative inside the silhouette, depth
    (P, B), world normal (P, B, 3)); objects behind the origin are far outside. ``kinds``
    (static ints, optional) names every object's kind so that only its primitive is computed
    (much faster); without it ``objects.kind`` may be traced and every primitive is computed.
    """
    outs = []
    for kind, start, stop in _groups(kinds, objects.kind.shape[0]):
        objs = objects if kind is None else _take(objects, start, stop)
        if kind == PLANE:
            outs.append(_plane_hits(origin, dirs, objs.pos, objs.size, extent))
            continue
        rot = quat_to_matrix(objs.quat)  # (B, 3, 3)
        o = _to_local(rot, (origin - objs.pos))  # (B,) each
        d = tuple(dirs @ rot[:, :, k].T for k in range(3))  # (P, B) each
        sd, tc, depth, n_local, front = convex_hits(o, d, objs.kind if kind is None else kind,
                                                    objs.size)
        ang = jnp.where(front, sd / tc, 1.0)
        normal = _to_world(rot, n_local)
        if kind is None:
            ang_p, depth_p, n_p = _plane_hits(origin, dirs, objs.pos, objs.size, extent)
            plane = objs.kind == PLANE
            ang, depth = jnp.where(plane, ang_p, ang), jnp.where(plane, depth_p, depth)
            normal = jnp.where(plane[:, None], n_p, normal)
        outs.append((ang, depth, normal))
    if len(outs) == 1:
        return outs[0]
    return tuple(jnp.concatenate([o[i] for o in outs], axis=1) for i in range(3))


def cast_from_points(points, direction, objects: Objects, kinds=None):
    """Rays from points (..., 3) along one unit ``direction`` (3,) against every convex object:
    (signed distance in m, closest-approach distance, in front) each (..., B); planes are
    reported as never in front. For shadows."""
    outs = []
    for kind, start, stop in _groups(kinds, objects.kind.shape[0]):
        objs = objects if kind is None else _take(objects, start, stop)
        if kind == PLANE:
            shape = points.shape[:-1] + (stop - start,)
            outs.append((jnp.ones(shape), jnp.ones(shape), jnp.zeros(shape, dtype=bool)))
            continue
        rot = quat_to_matrix(objs.quat)
        o = _to_local(rot, points[..., None, :] - objs.pos)
        d = tuple(rot[:, :, k] @ direction for k in range(3))  # (B,) each
        sd, tc, _, _, front = convex_hits(o, d, objs.kind if kind is None else kind, objs.size)
        outs.append((sd, tc, front & (objs.kind != PLANE)))
    if len(outs) == 1:
        return outs[0]
    return tuple(jnp.concatenate([o[i] for o in outs], axis=-1) for i in range(3))


assert CAPSULE == 3
