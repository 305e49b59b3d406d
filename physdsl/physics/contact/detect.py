"""Contact detection between primitive shapes: fixed-size candidate sets per kind pair.

``detect(kind_a, kind_b, ...)`` dispatches through ``PAIRS`` (table, not an if-chain); a pair
stored as (b, a) is evaluated swapped and its normal flipped. Every pair function returns
(dist (K,), normal (K,3) from B towards A, point_a (K,3), point_b (K,3), valid (K,)) with a
static K; ``active = valid & dist < margin``.

Size packing (3,): sphere (r, 0, 0); box half-extents; capsule/cylinder (r, half length of the
cylindrical part along local z, 0); plane: its unit normal, with pos a point on it.

Exact pairs: everything against a plane, sphere-sphere, sphere-box, sphere-capsule,
sphere-cylinder, capsule-capsule, capsule-box and capsule-cylinder (exact nearest point of the
axis, plus both end spheres for resting support), box-box while apart (8 + 8 vertices against
the other box and the nearest of the 144 edge pairs; penetrating edge-edge contacts are not
resolved). Approximate (rim points against the other solid, both ways; rim-edge contacts are
missed): box-cylinder, cylinder-cylinder.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp

from ...errors import ModelError
from .geometry import (box_closest, convex_line_min, cylinder_closest, quat_to_matrix,
                       safe_norm, safe_normalize, segment_closest_param, segments_closest)

SHAPE_CODES: dict[str, int] = {"sphere": 0, "box": 1, "cylinder": 2, "capsule": 3, "plane": 4}

contact_margin = 0.01  # m: candidates closer than this are active (speculative contacts)

_Z = jnp.array([0.0, 0.0, 1.0])
_X = jnp.array([1.0, 0.0, 0.0])


class ContactPoints(NamedTuple):
    """Fixed-size contact candidates between bodies A and B (world frame)."""

    dist: jnp.ndarray     # (K,) signed gap, negative = penetration
    normal: jnp.ndarray   # (K,3) unit, from B towards A
    point_a: jnp.ndarray  # (K,3) on A's surface
    point_b: jnp.ndarray  # (K,3) on B's surface
    active: jnp.ndarray   # (K,) bool


def _valid(k):
    return jnp.ones((k,), bool)


def _plane(pos, size):
    return safe_normalize(size, _Z), pos


def _against_plane(points, radius, n, p0):
    """Points (K,3) carrying spheres of ``radius`` against the plane (n, p0)."""
    d = (points - p0) @ n - radius
    pa = points - radius * n
    return d, jnp.broadcast_to(n, points.shape), pa, pa - d[:, None] * n, _valid(points.shape[0])


def _box_corners(pos, quat, half):
    signs = jnp.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    return pos + (signs * half) @ quat_to_matrix(quat).T


def _caps(pos, quat, half_length):
    axis = quat_to_matrix(quat)[:, 2]
    return jnp.stack([pos - half_length * axis, pos + half_length * axis]), axis


def _rim_points(pos, quat, radius, half_length, toward):
    """8 rim points of a cylinder: per cap, the rim point furthest along ``toward`` (world),
    the opposite one and the two at 90 degrees (supports a cylinder resting on a cap)."""
    R = quat_to_matrix(quat)
    axis = R[:, 2]
    u = safe_normalize(toward - jnp.dot(toward, axis) * axis, R[:, 0])
    w = jnp.cross(axis, u)
    rim = radius * jnp.stack([u, -u, w, -w])
    caps = jnp.stack([pos - half_length * axis, pos + half_length * axis])
    return (caps[:, None, :] + rim[None, :, :]).reshape(8, 3)


def _spheres(ca, ra, cb, rb):
    """Sphere (ca, ra) as A against sphere (cb, rb) as B, for single centres (3,)."""
    n = safe_normalize(ca - cb, _Z)
    d = safe_norm(ca - cb) - ra - rb
    return d, n, ca - ra * n, cb + rb * n


def _one(d, n, pa, pb):
    return d[None], n[None], pa[None], pb[None], _valid(1)


def _point_vs_solid(points, closest, pos_b, quat_b):
    """Points of A (K,3) against a solid B given its local ``closest`` function."""
    R = quat_to_matrix(quat_b)
    d, n_loc, s_loc = jax.vmap(closest)((points - pos_b) @ R)
    return d, n_loc @ R.T, points, pos_b + s_loc @ R.T, _valid(points.shape[0])


def _solid_closest(kind, size):
    if kind == "box":
        return lambda p: box_closest(p, size)
    return lambda p: cylinder_closest(p, size[0], size[1])


def _segment_vs_solid(pos_a, quat_a, size_a, kind_b, pos_b, quat_b, size_b):
    """Capsule A against a convex solid B: the axis point nearest B plus both end spheres.

    The nearest point minimises B's signed distance along the axis (convex), found by golden
    section; its gradient is exact by the envelope theorem. It is dropped (valid False) when it
    coincides with an end, so the end spheres are not counted twice.
    """
    r, hl = size_a[0], size_a[1]
    ends, axis = _caps(pos_a, quat_a, hl)
    R = quat_to_matrix(quat_b)
    closest = _solid_closest(kind_b, size_b)
    sdf = lambda t: closest((pos_a + t * axis - pos_b) @ R)[0]  # noqa: E731
    t = convex_line_min(sdf, -hl, hl)
    centres = jnp.concatenate([ends, (pos_a + t * axis)[None]])
    d, n, c, pb, _ = _point_vs_solid(centres, closest, pos_b, quat_b)
    valid = jnp.array([True, True, jnp.abs(t) < hl * (1 - 1e-6) - 1e-9])
    return d - r, n, c - r * n, pb, valid


# --- pair functions: (pos_a, quat_a, size_a, pos_b, quat_b, size_b) -> 5-tuple ------------

def sphere_plane(pa, qa, sa, pb, qb, sb):
    n, p0 = _plane(pb, sb)
    return _against_plane(pa[None], sa[0], n, p0)


def box_plane(pa, qa, sa, pb, qb, sb):
    n, p0 = _plane(pb, sb)
    return _against_plane(_box_corners(pa, qa, sa), 0.0, n, p0)


def capsule_plane(pa, qa, sa, pb, qb, sb):
    n, p0 = _plane(pb, sb)
    return _against_plane(_caps(pa, qa, sa[1])[0], sa[0], n, p0)


def cylinder_plane(pa, qa, sa, pb, qb, sb):
    n, p0 = _plane(pb, sb)
    return _against_plane(_rim_points(pa, qa, sa[0], sa[1], -n), 0.0, n, p0)


def sphere_sphere(pa, qa, sa, pb, qb, sb):
    return _one(*_spheres(pa, sa[0], pb, sb[0]))


def sphere_box(pa, qa, sa, pb, qb, sb):
    d, n, _, s, v = _point_vs_solid(pa[None], _solid_closest("box", sb), pb, qb)
    return d - sa[0], n, pa[None] - sa[0] * n, s, v


def sphere_cylinder(pa, qa, sa, pb, qb, sb):
    d, n, _, s, v = _point_vs_solid(pa[None], _solid_closest("cylinder", sb), pb, qb)
    return d - sa[0], n, pa[None] - sa[0] * n, s, v


def sphere_capsule(pa, qa, sa, pb, qb, sb):
    axis = quat_to_matrix(qb)[:, 2]
    c = pb + segment_closest_param(pb, axis, sb[1], pa) * axis
    return _one(*_spheres(pa, sa[0], c, sb[0]))


def capsule_capsule(pa, qa, sa, pb, qb, sb):
    ua, ub = quat_to_matrix(qa)[:, 2], quat_to_matrix(qb)[:, 2]
    ca, cb = segments_closest(pa, ua, sa[1], pb, ub, sb[1])
    return _one(*_spheres(ca, sa[0], cb, sb[0]))


def capsule_box(pa, qa, sa, pb, qb, sb):
    return _segment_vs_solid(pa, qa, sa, "box", pb, qb, sb)


def capsule_cylinder(pa, qa, sa, pb, qb, sb):
    return _segment_vs_solid(pa, qa, sa, "cylinder", pb, qb, sb)


def _both_ways(points_a, kind_a, pa, qa, sa, points_b, kind_b, pb, qb, sb):
    """Points of A against solid B, then points of B against solid A (flipped)."""
    ab = _point_vs_solid(points_a, _solid_closest(kind_b, sb), pb, qb)
    d, n, p_on_b, p_on_a, v = _point_vs_solid(points_b, _solid_closest(kind_a, sa), pa, qa)
    ba = (d, -n, p_on_a, p_on_b, v)
    return tuple(jnp.concatenate([x, y]) for x, y in zip(ab, ba))


def _box_edges(pos, quat, half):
    """The 12 edges of a box: centres (12,3), unit directions (12,3), half lengths (12,)."""
    R = quat_to_matrix(quat)
    centres, dirs, lengths = [], [], []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        for si in (-1.0, 1.0):
            for sj in (-1.0, 1.0):
                centres.append(pos + si * half[i] * R[:, i] + sj * half[j] * R[:, j])
                dirs.append(R[:, k])
                lengths.append(half[k])
    return jnp.stack(centres), jnp.stack(dirs), jnp.stack(lengths)


def _nearest_edges(pa, qa, sa, pb, qb, sb):
    """The closest pair among the 12 x 12 edges of two separated boxes (one candidate).

    Valid only while both closest points lie outside the other box: edge-edge penetration is
    not resolved (the speculative margin makes the LCP stop edges before they cross).
    """
    ca, ua, la = _box_edges(pa, qa, sa)
    cb, ub, lb = _box_edges(pb, qb, sb)
    seg = jax.vmap(jax.vmap(segments_closest, (None, None, None, 0, 0, 0)),
                   (0, 0, 0, None, None, None))
    xa, xb = seg(ca, ua, la, cb, ub, lb)  # (12, 12, 3) each
    xa, xb = xa.reshape(-1, 3), xb.reshape(-1, 3)
    k = jnp.argmin(jnp.sum((xa - xb) ** 2, axis=1))
    xa, xb = xa[k], xb[k]
    Ra, Rb = quat_to_matrix(qa), quat_to_matrix(qb)
    axis = jnp.cross(ua[k // 12], ub[k % 12])
    axis = jnp.where(jnp.dot(axis, pa - pb) < 0, -axis, axis)  # oriented from B towards A
    axis = safe_normalize(axis, safe_normalize(pa - pb, _Z))
    n = safe_normalize(xa - xb, axis)
    outside = ((box_closest((xa - pb) @ Rb, sb)[0] >= 0) & (box_closest((xb - pa) @ Ra, sa)[0] >= 0))
    return safe_norm(xa - xb)[None], n[None], xa[None], xb[None], outside[None]


def box_box(pa, qa, sa, pb, qb, sb):
    vertices = _both_ways(_box_corners(pa, qa, sa), "box", pa, qa, sa,
                          _box_corners(pb, qb, sb), "box", pb, qb, sb)
    edges = _nearest_edges(pa, qa, sa, pb, qb, sb)
    return tuple(jnp.concatenate([x, y]) for x, y in zip(vertices, edges))


def cylinder_box(pa, qa, sa, pb, qb, sb):
    return _both_ways(_rim_points(pa, qa, sa[0], sa[1], pb - pa), "cylinder", pa, qa, sa,
                      _box_corners(pb, qb, sb), "box", pb, qb, sb)


def cylinder_cylinder(pa, qa, sa, pb, qb, sb):
    return _both_ways(_rim_points(pa, qa, sa[0], sa[1], pb - pa), "cylinder", pa, qa, sa,
                      _rim_points(pb, qb, sb[0], sb[1], pa - pb), "cylinder", pb, qb, sb)


PAIRS: dict[tuple[str, str], Callable] = {
    ("sphere", "plane"): sphere_plane,
    ("box", "plane"): box_plane,
    ("capsule", "plane"): capsule_plane,
    ("cylinder", "plane"): cylinder_plane,
    ("sphere", "sphere"): sphere_sphere,
    ("sphere", "box"): sphere_box,
    ("sphere", "cylinder"): sphere_cylinder,
    ("sphere", "capsule"): sphere_capsule,
    ("capsule", "capsule"): capsule_capsule,
    ("capsule", "box"): capsule_box,
    ("capsule", "cylinder"): capsule_cylinder,
    ("box", "box"): box_box,
    ("cylinder", "box"): cylinder_box,
    ("cylinder", "cylinder"): cylinder_cylinder,
}


# Pairs whose candidates exceed what can touch at once keep only the closest few: a box or a
# cylinder lies on a plane on at most four of its corners or rim points, so the other four are
# never active and would only enlarge the contact LCP (its cost grows with the cube of the rows).
KEEP_CLOSEST: dict[tuple[str, str], int] = {("box", "plane"): 4, ("cylinder", "plane"): 4}


def _closest(cp: tuple, k: int) -> tuple:
    """The ``k`` candidates of smallest gap (ties are far from contact, so which one is kept
    never changes an active contact)."""
    idx = jax.lax.top_k(-jax.lax.stop_gradient(cp[0]), k)[1]
    return tuple(x[idx] for x in cp)


def contact_count(kind_a: str, kind_b: str) -> int:
    """Static number K of candidates ``detect`` returns for this kind pair."""
    z3, q = jnp.zeros(3), jnp.array([1.0, 0, 0, 0])
    out = jax.eval_shape(lambda: detect(kind_a, kind_b, z3, q, jnp.ones(3), z3, q, _Z))
    return out.dist.shape[0]


def detect(kind_a: str, kind_b: str, pos_a, quat_a, size_a, pos_b, quat_b, size_b,
           margin: float = contact_margin) -> ContactPoints:
    """Contact candidates between A and B (kinds static strings; see module docstring)."""
    args = [jnp.asarray(x, dtype=float) for x in (pos_a, quat_a, size_a, pos_b, quat_b, size_b)]
    if (kind_a, kind_b) in PAIRS:
        cp = PAIRS[kind_a, kind_b](*args)
        keep = KEEP_CLOSEST.get((kind_a, kind_b))
        d, n, pa, pb, valid = _closest(cp, keep) if keep else cp
    elif (kind_b, kind_a) in PAIRS:
        cp = PAIRS[kind_b, kind_a](*args[3:], *args[:3])
        keep = KEEP_CLOSEST.get((kind_b, kind_a))
        d, n, pb, pa, valid = _closest(cp, keep) if keep else cp
        n = -n
    else:
        raise ModelError(f"no contact model between a {kind_a} and a {kind_b}",
                         hint="contact pairs supported: "
                              + ", ".join(f"{a}-{b}" for a, b in PAIRS))
    return ContactPoints(d, n, pa, pb, valid & (d < margin))
