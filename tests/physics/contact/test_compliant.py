"""Compliant contact: rebound restitution by direct simulation, the friction bound, smoothness."""
from functools import partial

import numpy as np

import physdsl  # noqa: F401  (float64)
import jax
import jax.numpy as jnp

from physdsl.physics.contact import compliant_forces as compliant_eager
from physdsl.physics.contact import damping_ratio as damping_eager
from physdsl.physics.contact.compliant import _log_restitution

compliant_forces = jax.jit(compliant_eager)  # op-by-op dispatch would compile each primitive
damping_ratio = jax.jit(damping_eager)

E = jnp.array([1.0, 0.8, 0.5, 0.2])
M = 2.0


@partial(jax.jit, static_argnames=("g", "h", "steps"))
def fall(e, z0, v0, g, h, steps):
    """Semi-implicit Euler of a point mass over the ground z = 0 (dist = z)."""
    def f(s, _):
        z, v = s
        fn, _ = compliant_eager(z[None], v[None], jnp.zeros((1, 3)), jnp.zeros(1), e[None],
                                 jnp.array([M]))
        v = v + h * (fn[0] / M - g)
        z = z + h * v
        return (z, v), (z, v)
    return jax.lax.scan(f, (z0, v0), None, length=steps)[1]


def measured_restitution(zs, vs, height):
    """Speed ratio at the same height going up and coming down (free flight is symmetric)."""
    zs, vs = np.asarray(zs), np.asarray(vs)
    i = int(np.argmax(zs < height))
    j = i + int(np.argmax(zs[i:] > height))
    assert j > i, "no rebound"
    return -vs[j] / vs[i]


def test_restitution_without_gravity_matches_e():
    zs, vs = jax.vmap(lambda e: fall(e, 0.02, -2.0, g=0.0, h=2e-5, steps=2500))(E)
    for k, e in enumerate(np.asarray(E)):
        assert abs(measured_restitution(zs[k], vs[k], 0.01) - e) < 5e-3 * e


def test_dropped_mass_rebounds_with_restitution_e():
    # dropped from 1 m (4.4 m/s at impact); gravity acting during the ~10 ms contact costs
    # O(g time_constant / v_in) of the rebound speed, hence the 0.05 tolerance
    zs, vs = jax.vmap(lambda e: fall(e, 1.0, 0.0, g=9.81, h=5e-5, steps=10000))(E)
    for k, e in enumerate(np.asarray(E)):
        assert abs(measured_restitution(zs[k], vs[k], 0.01) - e) < 0.05


def test_damping_ratio_inverts_clamped_restitution():
    e = jnp.array([1.0, 0.9, 0.5, 0.135, 0.05, 0.01])
    np.testing.assert_allclose(jnp.exp(_log_restitution(damping_ratio(e))), e, rtol=1e-9)
    g = jax.jit(jax.grad(lambda x: damping_eager(x).sum()))(jnp.array([0.3, 0.7]))
    x = jnp.array([0.3, 0.7])
    fd = (damping_ratio(x + 1e-6) - damping_ratio(x - 1e-6)) / 2e-6
    np.testing.assert_allclose(g, fd, rtol=1e-6)


def test_friction_bounded_by_mu_fn_and_opposes_sliding():
    rng = np.random.default_rng(0)
    C = 64
    dist = jnp.asarray(rng.uniform(-0.01, 0.002, C))
    vn = jnp.asarray(rng.normal(size=C))
    vt = jnp.asarray(rng.normal(size=(C, 3)) * rng.uniform(0, 2, (C, 1)))
    vt = vt.at[0].set(0.0)
    mu = jnp.asarray(rng.uniform(0, 1.2, C))
    fn, ft = compliant_forces(dist, vn, vt, mu, jnp.full(C, 0.5), jnp.ones(C))
    assert float(jnp.min(fn)) >= 0.0
    norm = jnp.linalg.norm(ft, axis=1)
    assert np.all(np.asarray(norm <= mu * fn * (1 + 1e-12) + 1e-300))
    assert np.all(np.asarray(jnp.sum(ft * vt, axis=1)) <= 0.0)
    np.testing.assert_array_equal(ft[0], 0.0)
    fast = jnp.linalg.norm(vt, axis=1) > 0.5  # well above friction_eps: nearly full Coulomb
    np.testing.assert_allclose(norm[fast], (mu * fn)[fast], rtol=1e-5)


def test_apart_is_force_free_and_gradients_are_finite():
    fn, ft = compliant_forces(jnp.array([0.01, 0.005]), jnp.array([-3.0, 0.0]),
                              jnp.ones((2, 3)), jnp.ones(2), jnp.array([0.5, 0.5]), jnp.ones(2))
    assert float(jnp.max(fn)) < 1e-12 and float(jnp.max(jnp.abs(ft))) < 1e-12

    @jax.jit
    def f(x):
        fn, ft = compliant_eager(x[:1], x[1:2], jnp.zeros((1, 3)), jnp.ones(1), x[2:3], jnp.ones(1))
        return fn[0] + jnp.sum(ft)

    grad_f = jax.jit(jax.grad(f))
    for d in (0.0, -1e-3, 1e-3):
        g = grad_f(jnp.array([d, -1.0, 0.5]))
        assert np.all(np.isfinite(np.asarray(g)))
    g = grad_f(jnp.array([-1e-3, -1.0, 0.5]))
    eps = 1e-8
    x0 = jnp.array([-1e-3, -1.0, 0.5])
    fd = [(f(x0.at[i].add(eps)) - f(x0.at[i].add(-eps))) / (2 * eps) for i in range(3)]
    np.testing.assert_allclose(g, fd, rtol=1e-5)
