"""Contact detection against hand-computed distances, normals and points; jit, vmap, gradients."""
import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
import jax
import jax.numpy as jnp

from physdsl.errors import ModelError
from physdsl.physics.contact import PAIRS, SHAPE_CODES, contact_count
from physdsl.physics.contact import detect as detect_eager

# jit once per kind pair: op-by-op dispatch would compile every primitive separately
_detect_jit = jax.jit(detect_eager, static_argnums=(0, 1))


def detect(kind_a, kind_b, *args):
    return _detect_jit(kind_a, kind_b, *(jnp.asarray(x, float) for x in args))

I = np.array([1.0, 0, 0, 0])
UP = np.array([0, 0, 1.0])


def quat_axis(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def deepest(cp):
    k = int(np.argmin(np.asarray(cp.dist)))
    return (float(cp.dist[k]), np.asarray(cp.normal[k]), np.asarray(cp.point_a[k]),
            np.asarray(cp.point_b[k]))


def test_shape_codes_and_table():
    assert set(SHAPE_CODES) == {"sphere", "box", "cylinder", "capsule", "plane"}
    assert len(set(SHAPE_CODES.values())) == 5
    for a, b in PAIRS:
        assert contact_count(a, b) == contact_count(b, a) > 0


def test_sphere_plane_both_orders():
    pos, r = np.array([0.3, -0.2, 0.45]), 0.5
    cp = detect("sphere", "plane", pos, I, [r, 0, 0], [0, 0, 0.1], I, UP)
    assert cp.dist.shape == (1,)
    np.testing.assert_allclose(cp.dist, [0.45 - 0.1 - 0.5])
    np.testing.assert_allclose(cp.normal[0], UP)
    np.testing.assert_allclose(cp.point_a[0], [0.3, -0.2, -0.05])
    np.testing.assert_allclose(cp.point_b[0], [0.3, -0.2, 0.1])
    assert bool(cp.active[0])
    sw = detect("plane", "sphere", [0, 0, 0.1], I, UP, pos, I, [r, 0, 0])
    np.testing.assert_allclose(sw.dist, cp.dist)
    np.testing.assert_allclose(sw.normal, -cp.normal)
    np.testing.assert_allclose(sw.point_a, cp.point_b)
    np.testing.assert_allclose(sw.point_b, cp.point_a)


def test_sphere_far_from_plane_is_inactive():
    cp = detect("sphere", "plane", [0, 0, 2.0], I, [0.5, 0, 0], [0, 0, 0], I, UP)
    assert not bool(cp.active[0])
    np.testing.assert_allclose(cp.dist, [1.5])


def test_tilted_plane():
    n = np.array([0, 1.0, 1.0]) / np.sqrt(2)
    cp = detect("sphere", "plane", [0, 0, 1.0], I, [0.2, 0, 0], [0, 0, 0], I, n)
    np.testing.assert_allclose(cp.dist, [1 / np.sqrt(2) - 0.2])
    np.testing.assert_allclose(cp.normal[0], n)


def test_rotated_box_on_plane():
    # Box half extents (0.5, 0.2, 0.1) rotated 45 deg about x: lowest corners at
    # z = c - (0.2 sin45 + 0.1 cos45).
    q = quat_axis([1, 0, 0], np.pi / 4)
    c = np.array([1.0, 2.0, 0.2])
    cp = detect("box", "plane", c, q, [0.5, 0.2, 0.1], [0, 0, 0], I, UP)
    assert cp.dist.shape == (4,)  # the four closest of the eight corners
    low = 0.2 - (0.2 + 0.1) / np.sqrt(2)
    second = 0.2 - (0.2 - 0.1) / np.sqrt(2)  # the next pair of corners up
    d = np.sort(np.asarray(cp.dist))
    np.testing.assert_allclose(d, [low, low, second, second], atol=1e-12)
    k = np.argsort(np.asarray(cp.dist))[:2]
    np.testing.assert_allclose(np.sort(np.asarray(cp.point_a)[k, 0]), [0.5, 1.5])
    np.testing.assert_allclose(np.asarray(cp.point_b)[k, 2], 0.0, atol=1e-12)
    np.testing.assert_array_equal(np.asarray(cp.active), np.asarray(cp.dist) < 0.01)


def test_rotated_capsule_on_plane():
    # Capsule r=0.1, half length 0.5, tilted 30 deg about y: lower end at z = c - 0.5 cos30.
    q = quat_axis([0, 1, 0], np.pi / 6)
    c = np.array([0.0, 0.0, 0.5])
    cp = detect("capsule", "plane", c, q, [0.1, 0.5, 0], [0, 0, 0], I, UP)
    assert cp.dist.shape == (2,)
    end_z = 0.5 - 0.5 * np.cos(np.pi / 6)
    np.testing.assert_allclose(np.min(cp.dist), end_z - 0.1)
    d, n, pa, pb = deepest(cp)
    np.testing.assert_allclose(pa, [-0.5 * np.sin(np.pi / 6), 0, end_z - 0.1], atol=1e-12)
    np.testing.assert_allclose(n, UP)


def test_cylinder_on_plane_side_and_upright():
    # lying on its side (axis along x), any spin about its axis: two lowest points on the line
    for spin in (0.0, 0.3, 1.1):
        q = np.asarray(jnp.asarray(quat_axis([0, 1, 0], np.pi / 2)))
        spin_q = quat_axis([0, 0, 1], spin)  # spin about local z = world x after the tilt
        w1, v1 = q[0], q[1:]
        w2, v2 = spin_q[0], spin_q[1:]
        qq = np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])
        cp = detect("cylinder", "plane", [0, 0, 0.29], qq, [0.3, 0.4, 0], [0, 0, 0], I, UP)
        d = np.sort(np.asarray(cp.dist))
        np.testing.assert_allclose(d[:2], [-0.01, -0.01], atol=1e-12)
    # upright: 8 rim points, all at the bottom cap's depth or the top's
    cp = detect("cylinder", "plane", [0, 0, 0.39], I, [0.3, 0.4, 0], [0, 0, 0], I, UP)
    d = np.sort(np.asarray(cp.dist))
    np.testing.assert_allclose(d[:4], -0.01, atol=1e-12)
    np.testing.assert_allclose(d[4:], 0.79, atol=1e-12)
    assert np.all(np.isfinite(jax.grad(lambda p: detect(
        "cylinder", "plane", p, I, [0.3, 0.4, 0], [0, 0, 0], I, UP).dist.sum())(jnp.array([0, 0, 0.39]))))


def test_sphere_sphere_both_orders_and_coincident():
    cp = detect("sphere", "sphere", [1.0, 0, 0], I, [0.3, 0, 0], [0, 0, 0], I, [0.8, 0, 0])
    np.testing.assert_allclose(cp.dist, [-0.1])
    np.testing.assert_allclose(cp.normal[0], [1, 0, 0])
    np.testing.assert_allclose(cp.point_a[0], [0.7, 0, 0])
    np.testing.assert_allclose(cp.point_b[0], [0.8, 0, 0])
    sw = detect("sphere", "sphere", [0, 0, 0], I, [0.8, 0, 0], [1.0, 0, 0], I, [0.3, 0, 0])
    np.testing.assert_allclose(sw.normal[0], [-1, 0, 0])
    g = jax.grad(lambda p: detect("sphere", "sphere", p, I, [0.3, 0, 0], p, I, [0.8, 0, 0])
                 .dist[0])(jnp.zeros(3))
    assert np.all(np.isfinite(np.asarray(g)))


def test_sphere_rotated_box():
    q = quat_axis([0, 0, 1], np.pi / 4)  # box half extents (1, 0.5, 0.5) turned 45 deg about z
    hb = [1.0, 0.5, 0.5]
    # sphere on the box's local +y face direction: local +y = world (-1, 1, 0)/sqrt2
    ny = np.array([-1.0, 1.0, 0]) / np.sqrt(2)
    for order in ("ab", "ba"):
        pa = 0.8 * ny
        if order == "ab":
            cp = detect("sphere", "box", pa, I, [0.2, 0, 0], [0, 0, 0], q, hb)
            n_expect = ny
        else:
            cp = detect("box", "sphere", [0, 0, 0], q, hb, pa, I, [0.2, 0, 0])
            n_expect = -ny
        np.testing.assert_allclose(cp.dist, [0.8 - 0.5 - 0.2], atol=1e-12)
        np.testing.assert_allclose(cp.normal[0], n_expect, atol=1e-12)
    # centre inside the box: nearest face is +z (depth 0.1)
    cp = detect("sphere", "box", [0.2, 0, 0.4], I, [0.2, 0, 0], [0, 0, 0], q, hb)
    np.testing.assert_allclose(cp.dist, [-0.1 - 0.2], atol=1e-12)
    np.testing.assert_allclose(cp.normal[0], UP, atol=1e-12)
    np.testing.assert_allclose(cp.point_b[0], [0.2, 0, 0.5], atol=1e-12)
    # near a corner: Euclidean distance to the corner
    corner = np.array([1.0, 0.5, 0.5])
    cp = detect("sphere", "box", corner + [0.3, 0.4, 0], I, [0.1, 0, 0], [0, 0, 0], I, hb)
    np.testing.assert_allclose(cp.dist, [0.5 - 0.1])
    np.testing.assert_allclose(cp.normal[0], [0.6, 0.8, 0])


def test_capsule_sphere_and_capsule_capsule():
    qx = quat_axis([0, 1, 0], np.pi / 2)  # local z -> world x
    cp = detect("capsule", "sphere", [0, 0, 0], qx, [0.1, 1.0, 0], [0.5, 0.4, 0], I, [0.2, 0, 0])
    np.testing.assert_allclose(cp.dist, [0.4 - 0.3])
    np.testing.assert_allclose(cp.normal[0], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(cp.point_a[0], [0.5, 0.1, 0], atol=1e-12)
    np.testing.assert_allclose(cp.point_b[0], [0.5, 0.2, 0], atol=1e-12)
    sw = detect("sphere", "capsule", [1.5, 0, 0], I, [0.2, 0, 0], [0, 0, 0], qx, [0.1, 1.0, 0])
    np.testing.assert_allclose(sw.dist, [0.5 - 0.3])  # beyond the end cap
    np.testing.assert_allclose(sw.normal[0], [1, 0, 0], atol=1e-12)
    # crossed capsules: A along x at z = 0.25, B along y at z = 0
    qy = quat_axis([1, 0, 0], np.pi / 2)
    cp = detect("capsule", "capsule", [0.3, 0, 0.25], qx, [0.1, 1.0, 0], [0, -0.2, 0], qy,
                [0.1, 1.0, 0])
    np.testing.assert_allclose(cp.dist, [0.05], atol=1e-12)
    np.testing.assert_allclose(cp.normal[0], UP, atol=1e-12)
    np.testing.assert_allclose(cp.point_a[0], [0, 0, 0.15], atol=1e-12)
    # parallel capsules side by side
    cp = detect("capsule", "capsule", [0.5, 0.3, 0], qx, [0.1, 1.0, 0], [0, 0, 0], qx, [0.1, 1.0, 0])
    np.testing.assert_allclose(cp.dist, [0.1], atol=1e-12)
    np.testing.assert_allclose(cp.normal[0], [0, 1, 0], atol=1e-12)


def test_capsule_box_and_sphere_cylinder():
    # capsule along x lying over a box top at z = 0.5, tilted down 10 deg towards +x
    q = quat_axis([0, 1, 0], np.pi / 2 + np.deg2rad(10))
    c = np.array([0.0, 0, 0.8])
    cp = detect("capsule", "box", c, q, [0.1, 0.5, 0], [0, 0, 0], I, [2.0, 2.0, 0.5])
    low_end_z = 0.8 - 0.5 * np.sin(np.deg2rad(10))
    np.testing.assert_allclose(np.min(cp.dist), low_end_z - 0.5 - 0.1, atol=1e-9)
    np.testing.assert_allclose(deepest(cp)[1], UP, atol=1e-9)
    # the capsule's middle above a narrow box: the nearest axis point is interior
    q0 = quat_axis([0, 1, 0], np.pi / 2)
    cp = detect("capsule", "box", [0.1, 0, 0.7], q0, [0.1, 1.0, 0], [0, 0, 0], I, [0.2, 0.2, 0.5])
    np.testing.assert_allclose(np.min(cp.dist), 0.1, atol=1e-9)
    assert np.sum(np.asarray(cp.active)) == 0
    # sphere next to a cylinder's side and above its cap
    cp = detect("sphere", "cylinder", [0.5, 0, 0.1], I, [0.1, 0, 0], [0, 0, 0], I, [0.3, 0.4, 0])
    np.testing.assert_allclose(cp.dist, [0.1])
    np.testing.assert_allclose(cp.normal[0], [1, 0, 0])
    cp = detect("cylinder", "sphere", [0, 0, 0], I, [0.3, 0.4, 0], [0.1, 0, 0.45], I, [0.1, 0, 0])
    np.testing.assert_allclose(cp.dist, [-0.05])
    np.testing.assert_allclose(cp.normal[0], -UP)


def test_box_box_stacked():
    # a 0.2-cube resting 1 mm into a bigger box top, turned 30 deg about z
    q = quat_axis([0, 0, 1], np.pi / 6)
    cp = detect("box", "box", [0.1, 0.2, 0.5 + 0.1 - 0.001], q, [0.1, 0.1, 0.1], [0, 0, 0], I,
                [1.0, 1.0, 0.5])
    assert cp.dist.shape == (17,)  # 8 + 8 vertices, the nearest edge pair
    d = np.sort(np.asarray(cp.dist))
    np.testing.assert_allclose(d[:4], -0.001, atol=1e-12)
    assert np.sum(np.asarray(cp.active)) == 4
    k = np.argsort(np.asarray(cp.dist))[:4]
    np.testing.assert_allclose(np.asarray(cp.normal)[k], np.tile(UP, (4, 1)), atol=1e-12)


def test_box_box_crossed_edges():
    # two long boxes turned 45 deg about x and y: their ridges cross, 0.52 - 2 (0.1 sqrt2) apart
    cp = detect("box", "box", [0.05, 0.1, 0.52], quat_axis([1, 0, 0], np.pi / 4), [0.4, 0.1, 0.1],
                [0, 0, 0], quat_axis([0, 1, 0], np.pi / 4), [0.1, 0.4, 0.1])
    d, n, pa, pb = deepest(cp)
    np.testing.assert_allclose(d, 0.52 - 0.2 * np.sqrt(2), atol=1e-12)
    np.testing.assert_allclose(n, UP, atol=1e-12)
    np.testing.assert_allclose(pa, [0.0, 0.1, 0.52 - 0.1 * np.sqrt(2)], atol=1e-12)
    np.testing.assert_allclose(pb, [0.0, 0.1, 0.1 * np.sqrt(2)], atol=1e-12)


def test_unknown_pair_is_a_model_error():
    with pytest.raises(ModelError):
        detect_eager("plane", "plane", [0, 0, 0], I, UP, [0, 0, 0], I, UP)
    with pytest.raises(ModelError):
        detect_eager("mesh", "sphere", [0, 0, 0], I, UP, [0, 0, 0], I, UP)


def test_jit_and_vmap():
    f = jax.jit(lambda p: detect("box", "plane", p, I, jnp.array([0.1, 0.2, 0.3]),
                                 jnp.zeros(3), I, UP))
    zs = jnp.linspace(0.1, 0.5, 5)
    ps = jnp.stack([jnp.zeros(5), jnp.zeros(5), zs], axis=1)
    out = jax.vmap(f)(ps)
    assert out.dist.shape == (5, 4)  # the four closest corners
    np.testing.assert_allclose(out.dist.min(axis=1), zs - 0.3)
    np.testing.assert_allclose(f(ps[0]).dist, out.dist[0])


CASES = [
    ("sphere", "plane", [0.1, 0.2, 0.29], quat_axis([1, 1, 0], 0.3), [0.3, 0, 0],
     [0, 0, 0], I, np.array([0.1, 0.2, 1.0]) / np.linalg.norm([0.1, 0.2, 1.0])),
    ("box", "plane", [0.1, 0.2, 0.25], quat_axis([1, 2, 3], 0.4), [0.3, 0.2, 0.1],
     [0, 0, 0], I, UP),
    ("capsule", "plane", [0.1, 0.2, 0.25], quat_axis([1, 2, 3], 0.4), [0.1, 0.3, 0],
     [0, 0, 0], I, UP),
    ("cylinder", "plane", [0.1, 0.2, 0.25], quat_axis([1, 2, 3], 0.4), [0.1, 0.3, 0],
     [0, 0, 0], I, UP),
    ("sphere", "sphere", [0.1, 0.2, 0.25], I, [0.2, 0, 0], [0.3, 0.1, 0.0], I, [0.15, 0, 0]),
    ("sphere", "box", [0.6, 0.35, 0.3], I, [0.1, 0, 0], [0, 0, 0], quat_axis([0, 0, 1], 0.2),
     [0.5, 0.3, 0.2]),
    ("capsule", "sphere", [0, 0, 0], quat_axis([1, 1, 0], 0.8), [0.1, 0.5, 0],
     [0.4, 0.1, 0.5], I, [0.2, 0, 0]),
    ("capsule", "capsule", [0, 0, 0], quat_axis([1, 1, 0], 0.8), [0.1, 0.5, 0],
     [0.2, -0.1, 0.4], quat_axis([0, 1, 1], 1.2), [0.1, 0.5, 0]),
    ("capsule", "box", [0.1, 0.2, 0.75], quat_axis([0, 1, 0.2], 1.4), [0.1, 0.4, 0],
     [0, 0, 0], quat_axis([0, 0, 1], 0.2), [0.5, 0.5, 0.5]),
    ("sphere", "cylinder", [0.45, 0.1, 0.2], I, [0.1, 0, 0], [0, 0, 0],
     quat_axis([1, 0, 0], 0.3), [0.3, 0.4, 0]),
    ("box", "box", [0.05, 0.1, 0.52], quat_axis([1, 0, 0], np.pi / 4), [0.4, 0.1, 0.1],
     [0, 0, 0], quat_axis([0, 1, 0], np.pi / 4), [0.1, 0.4, 0.1]),  # crossed edges apart
]


# box-box (the largest detector, ~6 CPU s to compile) runs in the slow suite only
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if c[:2] == ("box", "box")
                                  else c for c in CASES], ids=[f"{c[0]}-{c[1]}" for c in CASES])
def test_distance_gradients_match_finite_differences(case):
    ka, kb, pa, qa, sa, pb, qb, sb = case

    def dist(pa_, pb_):
        return detect_eager(ka, kb, pa_, qa, sa, pb_, qb, sb).dist

    @jax.jit
    def check(pa, pb):  # one compilation: autodiff, central differences, normals
        ga, gb = jax.jacrev(dist, argnums=(0, 1))(pa, pb)
        steps = 1e-6 * jnp.eye(3)
        fd_a = jax.vmap(lambda e: (dist(pa + e, pb) - dist(pa - e, pb)) / 2e-6, out_axes=1)(steps)
        fd_b = jax.vmap(lambda e: (dist(pa, pb + e) - dist(pa, pb - e)) / 2e-6, out_axes=1)(steps)
        cp = detect_eager(ka, kb, pa, qa, sa, pb, qb, sb)
        return ga, gb, fd_a, fd_b, cp.dist, cp.normal

    ga, gb, fd_a, fd_b, d, n = check(jnp.asarray(pa, float), jnp.asarray(pb, float))
    np.testing.assert_allclose(ga, fd_a, atol=1e-7)
    np.testing.assert_allclose(gb, fd_b, atol=1e-7)
    # the gradient of a single gap w.r.t. A's position is its normal (moving A along n opens it)
    k = int(np.argmin(np.asarray(d)))
    np.testing.assert_allclose(ga[k], n[k], atol=1e-7)


ORACLE_SIZES = {"sphere": [0.2, 0, 0], "capsule": [0.1, 0.3, 0], "cylinder": [0.15, 0.25, 0],
                "box": [0.3, 0.2, 0.1]}
EXACT_PAIRS = [("sphere", "sphere"), ("sphere", "box"), ("sphere", "capsule"),
               ("sphere", "cylinder"), ("capsule", "capsule"), ("capsule", "box"),
               ("capsule", "cylinder"), ("box", "box")]


def _mujoco_xml(ka, kb):
    def geom(kind, name):
        n = {"sphere": 1, "capsule": 2, "cylinder": 2, "box": 3}[kind]
        size = " ".join(str(x) for x in ORACLE_SIZES[kind][:n])
        return f'<body><freejoint/><geom name="{name}" type="{kind}" size="{size}"/></body>'
    return f"<mujoco><worldbody>{geom(ka, 'a')}{geom(kb, 'b')}</worldbody></mujoco>"


@pytest.mark.parametrize("ka,kb", EXACT_PAIRS, ids=[f"{a}-{b}" for a, b in EXACT_PAIRS])
def test_separation_distance_matches_mujoco(ka, kb):
    """Random separated poses: the smallest candidate gap equals MuJoCo's mj_geomDistance."""
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_string(_mujoco_xml(ka, kb))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    qa = rng.normal(size=(40, 4))
    qb = rng.normal(size=(40, 4))
    qa /= np.linalg.norm(qa, axis=1, keepdims=True)
    qb /= np.linalg.norm(qb, axis=1, keepdims=True)
    u = rng.normal(size=(40, 3))
    pb = u / np.linalg.norm(u, axis=1, keepdims=True) * rng.uniform(0.3, 0.9, (40, 1))
    ref = []
    for i in range(40):
        d.qpos[:] = np.r_[0, 0, 0, qa[i], pb[i], qb[i]]
        mujoco.mj_forward(m, d)
        ref.append(mujoco.mj_geomDistance(m, d, 0, 1, 10.0, None))
    ref = np.array(ref)
    sa, sb = jnp.asarray(ORACLE_SIZES[ka]), jnp.asarray(ORACLE_SIZES[kb])
    ours = jax.jit(jax.vmap(lambda qa_, pb_, qb_: detect_eager(
        ka, kb, jnp.zeros(3), qa_, sa, pb_, qb_, sb).dist.min()))(qa, pb, qb)
    apart = ref > 1e-3
    assert apart.sum() >= 15
    np.testing.assert_allclose(np.asarray(ours)[apart], ref[apart], atol=1e-8)
