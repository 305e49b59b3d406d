"""The contact LCP started from the last step's solution (``lcp_solve_warm``): the same motion
and derivatives as from a cold start, in fewer iterations; float64."""
import jax
import jax.numpy as jnp
import numpy as np

import physdsl  # noqa: F401  (float64)
from physdsl.physics.contact import (IPSettings, LCPSettings, build_lcp, lcp_residual,
                                     lcp_solve_warm, solve_lcp_step)

G, H, M = 9.81, 0.001, 2.0
JN_Z = jnp.array([[0.0, 0.0, 1.0]])
JT_XY = jnp.array([[[1.0, 0, 0], [0, 1.0, 0], [-1.0, 0, 0], [0, -1.0, 0]]])


def _step(vx, mu, warm, settings=LCPSettings()):
    """A point-mass ball resting on the plane z = 0, pushed along x (free velocity ``vx``)."""
    return solve_lcp_step(M * jnp.eye(3), jnp.array([vx, 0.0, -G * H]), JN_Z, JT_XY,
                          jnp.array([mu]), jnp.array([0.0]), jnp.array([0.0]),
                          jnp.array([0.0]), jnp.array([True]), H, settings, warm=warm)


def _pushes():
    """Free velocities from sticking (below mu g h = 0.0049 m/s) to sliding and back."""
    return np.concatenate([np.linspace(0.0, 0.012, 12), np.linspace(0.012, 0.001, 12)])


def test_warm_and_cold_starts_give_the_same_motion_and_derivatives():
    step = jax.jit(_step)
    warm = None
    for vx in _pushes():
        cold = step(vx, 0.5, None)
        hot = step(vx, 0.5, warm)
        np.testing.assert_allclose(hot.v, cold.v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(hot.lam_n, cold.lam_n, rtol=1e-10)
        net = lambda lam: lam[0, :2] - lam[0, 2:]  # noqa: E731  (opposite edges may share)
        np.testing.assert_allclose(net(hot.lam_t), net(cold.lam_t), rtol=0, atol=1e-12)
        # d v / d (push, mu): the implicit derivative at either solution
        jac = jax.jit(jax.jacfwd(lambda p, w: _step(p[0], p[1], w).v))
        np.testing.assert_allclose(jac(jnp.array([vx, 0.5]), warm),
                                   jac(jnp.array([vx, 0.5]), None), rtol=1e-7, atol=1e-9)
        warm = hot.solution


def test_a_warm_start_converges_where_a_cold_one_runs_out_of_iterations():
    """Five Newton iterations do not reach the tolerance from ones; from the last step's
    solution they do: the start is taken."""
    few = IPSettings(iterations=5)
    lcp = [build_lcp(M * jnp.eye(3), jnp.array([vx, 0.0, -G * H]), JN_Z, JT_XY,
                     jnp.array([0.5]), jnp.array([0.0]), jnp.array([0.0]), jnp.array([0.0]),
                     jnp.array([True]), H) for vx in (0.002, 0.0021)]
    start = lcp_solve_warm(lcp[0].A, lcp[0].q, None)
    cold = lcp_solve_warm(lcp[1].A, lcp[1].q, None, few)
    hot = lcp_solve_warm(lcp[1].A, lcp[1].q, start, few)
    scale = float(jnp.max(jnp.abs(lcp[1].q)))
    assert float(lcp_residual(lcp[1].A, lcp[1].q, cold[0])) > 1e-9 * scale
    assert float(lcp_residual(lcp[1].A, lcp[1].q, hot[0])) < 1e-12 * scale


def test_a_start_that_is_not_interior_is_a_cold_start():
    """Zeros (the state after a step with no contact near) start from ones: the same bits."""
    cold = _step(0.003, 0.5, None)
    zeros = _step(0.003, 0.5, (jnp.zeros(6), jnp.zeros(6)))
    for a, b in zip(jax.tree_util.tree_leaves(cold), jax.tree_util.tree_leaves(zeros)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
