"""The interior-point contact LCP: analytic cases, the elastic swap, and implicit gradients."""
from functools import partial

import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
import jax
import jax.numpy as jnp

from physdsl.physics.contact import (IPSettings, LCPSettings, build_lcp, lcp_residual, lcp_solve,
                                     restitution_threshold, solve_lcp_step)

G, H = 9.81, 0.01
JN_Z = jnp.array([[0.0, 0.0, 1.0]])
JT_XY = jnp.array([[[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]]])
step = jax.jit(lambda *a: solve_lcp_step(*a)[:3], static_argnums=(10,))


def ball_on_plane(m, v_free, mu, e=0.0, vn_pre=0.0, dist=0.0, active=True):
    """A point-mass ball (M = m I3) touching the plane z = 0 with one contact."""
    return step(m * jnp.eye(3), jnp.asarray(v_free, float), JN_Z, JT_XY, jnp.array([mu]),
                jnp.array([e]), jnp.array([vn_pre]), jnp.array([dist]), jnp.array([active]), H,
                LCPSettings())


def test_resting_contact():
    m = 2.0
    v, lam_n, lam_t = ball_on_plane(m, [0, 0, -G * H], mu=0.5)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)
    np.testing.assert_allclose(lam_n, [m * G * H], rtol=1e-10)
    assert lam_t.shape == (1, 4)


@pytest.mark.parametrize("vx", [0.02, 0.04])
def test_friction_sticks_below_the_cone(vx):
    m, mu = 2.0, 0.5  # needed impulse m vx = 0.04, 0.08 < mu m g h = 0.0981
    v, lam_n, lam_t = ball_on_plane(m, [vx, 0, -G * H], mu=mu)
    np.testing.assert_allclose(v, 0.0, atol=1e-10)
    np.testing.assert_allclose(lam_t[0, 1] - lam_t[0, 0], m * vx, rtol=1e-8)
    assert float(jnp.sum(lam_t)) <= mu * float(lam_n[0]) * (1 + 1e-9)


@pytest.mark.parametrize("vx,vy", [(0.05, 0.0), (0.5, 0.0), (0.0, -0.3)])
def test_friction_slides_above_the_cone(vx, vy):
    m, mu = 2.0, 0.5
    v, lam_n, lam_t = ball_on_plane(m, [vx, vy, -G * H], mu=mu)
    slide = mu * G * H  # velocity removed by the full cone impulse mu m g h / m
    expect = [np.sign(vx) * max(abs(vx) - slide, 0), np.sign(vy) * max(abs(vy) - slide, 0), 0.0]
    np.testing.assert_allclose(v, expect, atol=1e-10)
    np.testing.assert_allclose(jnp.sum(lam_t), mu * lam_n[0], rtol=1e-8)


def test_frictionless_rows_are_inert():
    v, _, lam_t = ball_on_plane(2.0, [0.7, -0.2, -G * H], mu=0.0)
    np.testing.assert_allclose(v, [0.7, -0.2, 0.0], atol=1e-12)
    np.testing.assert_array_equal(lam_t, 0.0)


def test_elastic_bounce_and_threshold():
    # the impact is at the start of the step (dist 0): restitution, then a step of gravity
    v, _, _ = ball_on_plane(1.0, [0.0, 0, -2.0 - G * H], mu=0.3, e=1.0, vn_pre=-2.0)
    np.testing.assert_allclose(v, [0, 0, 2.0 - G * H], atol=1e-10)
    v, _, _ = ball_on_plane(1.0, [0.0, 0, -2.0 - G * H], mu=0.3, e=0.5, vn_pre=-2.0)
    np.testing.assert_allclose(v, [0, 0, 1.0 - G * H], atol=1e-10)
    slow = -0.5 * restitution_threshold  # below the threshold: no bounce
    v, _, _ = ball_on_plane(1.0, [0.0, 0, slow], mu=0.3, e=1.0, vn_pre=slow)
    np.testing.assert_allclose(v, 0.0, atol=1e-10)


def test_impact_within_the_step_is_split_at_the_time_of_impact():
    # 3 mm above the floor, falling at 1.2 m/s, 10 ms step: contact after tau = 2.5 ms at the
    # speed of the linear in-step velocity, rebound with e, gravity for the remaining 7.5 ms
    d, u0, e = 0.003, -1.2 + G * H, 0.8
    u1 = u0 - G * H
    tau = d / -u1
    v_hit = u0 - G * tau
    expect = -e * v_hit - G * (H - tau)
    out = solve_lcp_step(jnp.eye(3), jnp.array([0.0, 0, u1]), JN_Z, JT_XY, jnp.array([0.3]),
                         jnp.array([e]), jnp.array([u0]), jnp.array([d]), jnp.array([True]), H)
    np.testing.assert_allclose(out.v[2], expect, rtol=1e-10)
    # positions advance so that the step ends where the split motion puts the ball
    np.testing.assert_allclose(d + H * out.v_position[2], (H - tau) * expect, atol=1e-12)


def test_split_impact_is_continuous_across_step_boundaries():
    """Dropping from heights that put the impact just before or just after a step boundary
    gives the same trajectory (to O(g h^2)), so the fit's likelihood has no sawtooth."""
    @jax.jit
    def drop(d):
        def one(state, _):
            z, v = state
            u1 = v - G * H
            out = solve_lcp_step(jnp.eye(3), jnp.array([0.0, 0, u1]), JN_Z, jnp.zeros((1, 0, 3)),
                                 jnp.zeros(1), jnp.array([0.9]), jnp.array([v]),
                                 jnp.array([z]), jnp.array([z < 0.01]), H)
            z = z + H * out.v_position[2]
            return (z, out.v[2]), z
        return jax.lax.scan(one, (d, 0.0 * d), None, length=40)[1]

    # the free fall from 0.05 m crosses z = 0 near step 10 (t = 0.101 s)
    base = drop(0.05)
    heights = np.linspace(0.0495, 0.0505, 21)
    finals = np.asarray(jax.vmap(drop)(jnp.asarray(heights))[:, -1])
    jumps = np.abs(np.diff(finals))
    assert np.max(jumps) < 5 * np.median(jumps) + 2 * G * H * H  # no step-sized jump
    assert np.min(base) > -1e-9  # never below the floor


def test_penetration_is_pushed_out_and_gaps_may_close():
    beta = LCPSettings().baumgarte
    v, _, _ = ball_on_plane(1.0, [0, 0, -G * H], mu=0.3, dist=-0.002)
    np.testing.assert_allclose(v[2], beta * 0.002 / H, rtol=1e-9)
    # a speculative contact 1 mm away: the ball may approach at 0.1 m/s but not faster
    v, _, _ = ball_on_plane(1.0, [0, 0, -0.05], mu=0.3, dist=0.001, vn_pre=-0.05)
    np.testing.assert_allclose(v[2], -0.05, atol=1e-10)
    v, lam_n, _ = ball_on_plane(1.0, [0, 0, -0.02], mu=0.3, dist=0.0001, vn_pre=-0.02)
    np.testing.assert_allclose(v[2], -0.0001 / H, rtol=1e-9)
    # a perfectly plastic impact within the step stops the ball on the surface
    out = solve_lcp_step(jnp.eye(3), jnp.array([0.0, 0, -0.5]), JN_Z, JT_XY, jnp.array([0.3]),
                         jnp.array([0.0]), jnp.array([-0.5]), jnp.array([0.001]),
                         jnp.array([True]), H)
    np.testing.assert_allclose(out.v[2], 0.0, atol=1e-10)
    np.testing.assert_allclose(0.001 + H * out.v_position[2], 0.0, atol=1e-12)


def test_inactive_contacts_are_inert():
    m = 2.0
    rng = np.random.default_rng(0)
    Jn = jnp.concatenate([JN_Z, jnp.asarray(rng.normal(size=(2, 3)))])
    Jt = jnp.concatenate([JT_XY, jnp.asarray(rng.normal(size=(2, 4, 3)))])
    args = (jnp.array([0.5, 0.9, 0.2]), jnp.array([0.0, 1.0, 0.5]), jnp.array([0.0, -3.0, -1.0]),
            jnp.array([0.0, -0.1, -0.2]), jnp.array([True, False, False]), H)

    def f(Jn, Jt, v_free):
        return step(m * jnp.eye(3), v_free, Jn, Jt, *args, LCPSettings())

    v_free = jnp.array([0.2, 0, -G * H])
    v, lam_n, lam_t = f(Jn, Jt, v_free)
    v1, lam1, _ = ball_on_plane(m, v_free, mu=0.5)
    np.testing.assert_allclose(v, v1, atol=1e-12)
    np.testing.assert_array_equal(lam_n[1:], 0.0)
    np.testing.assert_array_equal(lam_t[1:], 0.0)
    gJn, gJt = jax.grad(lambda a, b: jnp.sum(f(a, b, v_free)[0] ** 2), argnums=(0, 1))(Jn, Jt)
    np.testing.assert_array_equal(gJn[1:], 0.0)
    np.testing.assert_array_equal(gJt[1:], 0.0)


def test_no_contacts():
    v, lam_n, lam_t, *_ = solve_lcp_step(jnp.eye(2), jnp.ones(2), jnp.zeros((0, 2)),
                                        jnp.zeros((0, 4, 2)), *(jnp.zeros(0),) * 4,
                                        jnp.zeros(0, bool), H)
    np.testing.assert_array_equal(v, 1.0)
    assert lam_n.shape == (0,) and lam_t.shape == (0, 4)


@partial(jax.jit, static_argnames=("m", "implicit"))
def two_balls(v_minus, e=1.0, m=(1.0, 1.0), implicit=True):
    """Head-on collision along x: contact row Jn = [-1, 1] (gap between ball 2 and ball 1)."""
    settings = LCPSettings(solver=IPSettings(implicit=implicit))
    Jn = jnp.array([[-1.0, 1.0]])
    return solve_lcp_step(jnp.diag(jnp.asarray(m)), v_minus, Jn, jnp.zeros((1, 4, 2)),
                          jnp.zeros(1), jnp.array([e]), Jn @ v_minus, jnp.zeros(1),
                          jnp.array([True]), H, settings).v


def test_elastic_head_on_collision_swaps_velocities_and_jacobian():
    v_minus = jnp.array([1.5, -0.5])
    np.testing.assert_allclose(two_balls(v_minus), [-0.5, 1.5], atol=1e-12)
    jac = jax.jit(jax.jacrev(two_balls))(v_minus)
    np.testing.assert_allclose(jac, [[0.0, 1.0], [1.0, 0.0]], atol=1e-10)
    # unequal masses: momentum and energy conserved, the classic 1D result
    m1, m2 = 1.0, 3.0
    v = two_balls(v_minus, m=(m1, m2))
    u1, u2 = v_minus
    np.testing.assert_allclose(v, [((m1 - m2) * u1 + 2 * m2 * u2) / (m1 + m2),
                                   ((m2 - m1) * u2 + 2 * m1 * u1) / (m1 + m2)], atol=1e-10)


def test_kkt_residual_small_at_solution():
    for seed in range(3):
        A, q, z, w = solve_zw(random_problem(seed))
        assert float(lcp_residual(A, q, z)) < 1e-12 * float(jnp.max(jnp.abs(q)))
        assert float(jnp.min(z)) >= 0.0
        assert float(jnp.min(w)) > -1e-12 * float(jnp.max(jnp.abs(q)))


def random_problem(seed, n=6, C=3, F=4):
    """A well-conditioned random contact step: SPD M, compressive contacts, mixed friction."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(n, n))
    M = B @ B.T + n * np.eye(n)
    Jn = rng.normal(size=(C, n))
    t1 = rng.normal(size=(C, n))
    t2 = rng.normal(size=(C, n))
    Jt = np.stack([t1, -t1, t2, -t2], axis=1)
    v_free = -0.5 * np.linalg.lstsq(Jn, np.ones(C), rcond=None)[0] + 0.05 * rng.normal(size=n)
    mu = rng.uniform(0.3, 1.0, C)
    e = rng.uniform(0.2, 0.8, C)
    vn_pre = -rng.uniform(0.5, 1.0, C)
    dist = np.zeros(C)
    active = np.ones(C, bool)
    return tuple(jnp.asarray(x) for x in (M, v_free, Jn, Jt, mu, e, vn_pre, dist, active))


@jax.jit
def solve_zw(p):
    lcp = build_lcp(*p[:9], H)
    z = lcp_solve(lcp.A, lcp.q)
    return lcp.A, lcp.q, z, lcp.A @ z + lcp.q


def strictly_complementary(p, gap=1e-4):
    """Away from kinks: each pair has z or w clearly positive (FD across a kink is meaningless)."""
    _, _, z, w = solve_zw(p)
    C = p[2].shape[0]
    zw = jnp.maximum(z, w)
    # friction direction pairs may both be zero when sticking; check normal and cone rows
    return bool(jnp.min(zw[:C]) > gap and jnp.min(zw[-C:]) > gap)


def loss_fn(implicit):
    settings = LCPSettings(solver=IPSettings(implicit=implicit))
    rng = np.random.default_rng(99)
    wv, wl = jnp.asarray(rng.normal(size=6)), jnp.asarray(rng.normal(size=3))

    def loss(theta, p):
        M, v_free, Jn, Jt, mu, e, vn_pre, dist, active = p
        M = M + theta["dM"]
        v, lam_n, *_ = solve_lcp_step(M, v_free + theta["dv"], Jn, Jt, mu + theta["dmu"],
                                      e + theta["de"], vn_pre, dist, active, H, settings)
        return jnp.dot(wv, v) + jnp.dot(wl, lam_n) / H

    return loss


def zero_theta():
    return {"dM": jnp.zeros((6, 6)), "dv": jnp.zeros(6), "dmu": jnp.zeros(3), "de": jnp.zeros(3)}


def fd_directions(rng):
    """Each v_free, mu, e entry, and four symmetric perturbations of M."""
    dirs = []
    for key, shape in (("dv", (6,)), ("dmu", (3,)), ("de", (3,))):
        for i in range(shape[0]):
            d = zero_theta()
            d[key] = d[key].at[i].set(1.0)
            dirs.append(d)
    for _ in range(4):
        S = rng.normal(size=(6, 6))
        d = zero_theta()
        d["dM"] = jnp.asarray(S + S.T)
        dirs.append(d)
    return dirs


def fd_seeds():
    """Three random problems away from kinks (FD across a kink is meaningless)."""
    seeds = [s for s in range(12) if strictly_complementary(random_problem(s))][:3]
    assert len(seeds) == 3
    return seeds


def test_implicit_gradients_match_finite_differences():
    grad_implicit = jax.jit(jax.grad(loss_fn(True)))
    loss_j = jax.jit(loss_fn(True))
    # the loss is O(1e3) here: FD carries ~1e-14 relative solver noise / eps, hence the atol
    rng = np.random.default_rng(1)
    for seed in fd_seeds():
        p = random_problem(seed)
        th = zero_theta()
        g = grad_implicit(th, p)
        eps = 1e-5
        scale = max(float(jnp.max(jnp.abs(x))) for x in jax.tree.leaves(g))
        for d in fd_directions(rng):
            plus = jax.tree.map(lambda a, b: a + eps * b, th, d)
            minus = jax.tree.map(lambda a, b: a - eps * b, th, d)
            fd = (loss_j(plus, p) - loss_j(minus, p)) / (2 * eps)
            an = sum(jnp.vdot(g[k], d[k]) for k in th)
            assert abs(float(an - fd)) <= 1e-3 * abs(float(fd)) + 1e-8 * scale, (seed, d, an, fd)


@pytest.mark.slow
def test_implicit_gradients_match_unrolling():
    """The implicit KKT gradient equals differentiating the solver's unrolled iterations."""
    grad_implicit = jax.jit(jax.grad(loss_fn(True)))
    grad_unrolled = jax.jit(jax.grad(loss_fn(False)))
    for seed in fd_seeds():
        p = random_problem(seed)
        th = zero_theta()
        g, gu = grad_implicit(th, p), grad_unrolled(th, p)
        for k in th:
            np.testing.assert_allclose(g[k], gu[k], rtol=1e-5, atol=1e-8)


def box_rows(half, normal_points):
    """Contact rows of a free box (v = (linear, angular) at its centre) at world offsets r."""
    rows_n, rows_t = [], []
    for r in normal_points:
        rx = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
        Jp = np.hstack([np.eye(3), -rx])  # velocity of the point: v + w x r
        rows_n.append(Jp[2])
        rows_t.append(np.stack([Jp[0], -Jp[0], Jp[1], -Jp[1]]))
    return jnp.asarray(np.array(rows_n)), jnp.asarray(np.array(rows_t))


def test_box_resting_on_four_redundant_corners():
    # 4 coplanar contacts on 6 DOF: the normal impulses are not unique, the velocity is
    m, a = 3.0, 0.1
    corners = [(sx * a, sy * a, -a) for sx in (-1, 1) for sy in (-1, 1)]
    Jn, Jt = box_rows(a, corners)
    M = jnp.diag(jnp.array([m, m, m] + [m * (2 * a) ** 2 / 6] * 3))
    f = jax.jit(lambda vf: solve_lcp_step(M, vf, Jn, Jt, jnp.full(4, 0.4), jnp.zeros(4),
                                          jnp.zeros(4), jnp.zeros(4), jnp.ones(4, bool), H)[:3])
    jac = jax.jit(jax.jacrev(lambda x: f(x)[0]))
    for vx in (0.0, 0.3):  # resting, and sliding (mu m g h removes mu g h of speed)
        v_free = jnp.array([vx, 0, -G * H, 0, 0, 0])
        v, lam_n, lam_t = f(v_free)
        np.testing.assert_allclose(v[2:], 0.0, atol=1e-9)
        np.testing.assert_allclose(v[0], max(vx - 0.4 * G * H, 0.0), atol=1e-9)
        np.testing.assert_allclose(jnp.sum(lam_n), m * G * H, rtol=1e-9)
        assert np.all(np.isfinite(np.asarray(jac(v_free))))
