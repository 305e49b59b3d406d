"""iLQR (physdsl.control.ilqr) against the exact optimum of a linear-quadratic problem (a
double integrator: the plan minimising a quadratic cost is one linear solve), and its guard:
a step whose rollout overflows is never taken."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import physdsl  # noqa: F401  (float64)
from physdsl.control import ilqr

DT = 0.1
A = jnp.array([[1.0, DT], [0.0, 1.0]])
B = jnp.array([[0.5 * DT ** 2], [DT]])


def f(x, w):
    return A @ x + B @ w


def stage(x, w):
    return x @ jnp.diag(jnp.array([1.0, 0.1])) @ x + 0.01 * w @ w


def final(x):
    return 10.0 * x @ x


def test_iterations_reach_the_exact_lq_optimum():
    """One iteration is the optimum up to the regularisation (1e-6 on the control Hessian of
    ~0.02: 1e-4 relative); the second removes that."""
    x0, H = jnp.array([1.0, -0.5]), 20
    once, _, _ = ilqr.solve(f, stage, final, x0, jnp.zeros((H, 1)), iterations=1)
    W, X, cost = ilqr.solve(f, stage, final, x0, jnp.zeros((H, 1)), iterations=2)
    total = lambda w: ilqr.total_cost(stage, final, ilqr.rollout(f, x0, w.reshape(H, 1)),  # noqa: E731
                                      w.reshape(H, 1))
    w0 = jnp.zeros(H)
    exact = -jnp.linalg.solve(jax.hessian(total)(w0), jax.grad(total)(w0))
    assert np.allclose(np.ravel(once), exact, rtol=1e-3, atol=1e-6)
    assert np.allclose(np.ravel(W), exact, atol=1e-8)
    assert np.isclose(float(cost), float(total(exact)), rtol=1e-10)
    assert np.allclose(X, ilqr.rollout(f, x0, W))


def test_a_step_that_overflows_is_not_taken():
    def fragile(x, w):  # NaN once a force exceeds 0.5: the full iLQR step does
        return jnp.where(jnp.abs(w[0]) > 0.5, jnp.nan, 1.0) * f(x, w)

    x0 = jnp.array([1.0, -0.5])
    W, X, cost = ilqr.solve(fragile, stage, final, x0, jnp.zeros((20, 1)), iterations=3)
    assert np.all(np.isfinite(np.asarray(W))) and np.isfinite(float(cost))
    assert float(cost) < float(ilqr.total_cost(stage, final, ilqr.rollout(f, x0, jnp.zeros((20, 1))),
                                               jnp.zeros((20, 1))))
    assert np.max(np.abs(np.asarray(W))) <= 0.5


def test_at_the_top_of_the_cost_one_iteration_goes_most_of_the_way_down():
    """A cost with its maximum at the start (10 cos x: a pole hanging where the chord cost
    peaks): the control Hessian is negative there; with its absolute eigenvalues (saddle-free)
    one iteration takes the end state past a quarter turn, on the side the start leaned to."""
    def g(x, w):
        return x + 0.1 * w

    def flat(x, w):
        return 1e-3 * w @ w

    def top(x):
        return 10.0 * jnp.cos(x[0])

    x0, W0 = jnp.array([0.01]), jnp.zeros((10, 1))
    W, X, cost = ilqr.solve(g, flat, top, x0, W0, iterations=1)
    assert np.all(np.isfinite(np.asarray(W)))
    assert float(X[-1, 0]) > np.pi / 2  # 10 cos x < 0: down from the top's 10
    assert float(cost) < 0.0


def test_warm_start_from_another_states_trajectory_reaches_the_optimum_in_one_iteration():
    """The receding-horizon warm start: the last plan's trajectory (here a rollout from another
    state) as ``guess``. For linear dynamics and a quadratic cost the feedback policy around any
    rollout is exact for every start, so one iteration from the new state is the optimum (up to
    the regularisation), without a rollout of the old plan from it."""
    x0, other, H = jnp.array([1.0, -0.5]), jnp.array([0.7, 0.2]), 20
    W0 = 0.3 * jnp.sin(jnp.arange(H, dtype=float))[:, None]
    guess = ilqr.rollout(f, other, W0)
    W, X, cost = ilqr.solve(f, stage, final, x0, W0, iterations=1, guess=guess)
    exact, _, best = ilqr.solve(f, stage, final, x0, jnp.zeros((H, 1)), iterations=3)
    assert np.allclose(W, exact, rtol=1e-3, atol=1e-6)
    assert np.allclose(X, ilqr.rollout(f, x0, W), atol=1e-12)
    assert np.isclose(float(cost), float(best), rtol=1e-6)


def test_linearised_in_motion_a_smoothed_friction_does_not_stall_the_plan():
    """A block at rest under Coulomb friction smoothed as tanh(v / 0.01), to be pushed to 1 m in
    2 s. At rest the friction's slope (100x its force) makes the linearised velocity flip sign
    every step, and one iteration from rest goes almost nowhere; linearised in motion (the mean
    Jacobian at v +- 0.2 m/s, where the friction is a constant force) one iteration takes the
    block most of the way, and further iterations agree."""
    dt, H = 0.1, 20

    def block(x, w):
        a = w[0] - 1.0 * jnp.tanh(x[1] / 0.01)
        return jnp.array([x[0] + dt * x[1] + dt ** 2 * a, x[1] + dt * a])

    def effort(x, w):
        return 1e-3 * w @ w

    def reach(x):
        return 100.0 * ((x[0] - 1.0) ** 2 + x[1] ** 2)

    x0, W0 = jnp.zeros(2), jnp.zeros((H, 1))
    motion = jnp.array([0.0, 0.2])
    guess = ilqr.rollout(block, x0, W0)
    _, X_rest, _ = ilqr.solve(block, effort, reach, x0, W0, 1, guess=guess)
    _, X_move, _ = ilqr.solve(block, effort, reach, x0, W0, 1, guess=guess, motion=motion)
    _, X_many, _ = ilqr.solve(block, effort, reach, x0, W0, 8, guess=guess, motion=motion)
    assert abs(float(X_rest[-1, 0]) - 1.0) > 0.5
    assert abs(float(X_move[-1, 0]) - 1.0) < 0.1
    assert abs(float(X_many[-1, 0]) - 1.0) < 0.05
