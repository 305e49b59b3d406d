"""The mode search (initialisation of every backend, and ``map``): Levenberg-Marquardt on the
Gauss-Newton curvature where the likelihood is least squares, L-BFGS elsewhere; both cross
regions where the log density is not concave instead of crawling through them."""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

# a prior draw of the projectile (unconstrained: velocity, log drag) from which the search
# meets negative curvature: with stale curvature pairs it crept 0.009 per step and was still
# 80 nats below the mode after 300 steps
HARD_START = np.array([2.49734439, 0.12586634, 2.57560951, -3.7980324])
EASY_START = np.array([3.1, 0.3, 4.2, np.log(0.25)])


def _counting(fn, counter: list):
    def counted(x):
        counter.append(1)
        return fn(x)
    return counted


def test_both_searches_cross_a_non_concave_region_to_one_mode(projectile_model):
    from physdsl.infer import levenberg_marquardt
    from physdsl.infer.backends.map import find_mode, lbfgs
    from physdsl.infer.base import gauss_newton_fn, value_and_grad_fn, value_fn
    from physdsl.infer.problem import model_problem

    problem = model_problem(projectile_model)
    vg = value_and_grad_fn(problem)
    reference = find_mode(problem, EASY_START, steps=100)
    lm_calls, lbfgs_calls = [], []
    by_lm = levenberg_marquardt.run(_counting(gauss_newton_fn(problem), lm_calls), HARD_START, 100,
                                _counting(value_fn(problem), lm_calls))
    by_lbfgs = lbfgs(_counting(vg, lbfgs_calls), HARD_START, 100)
    for mode in (by_lm, by_lbfgs):
        assert float(vg(jnp.asarray(mode))[0]) > float(vg(jnp.asarray(reference))[0]) - 1e-6
        assert np.max(np.abs(np.asarray(vg(jnp.asarray(mode))[1]))) < 1e-3
        np.testing.assert_allclose(mode, reference, atol=1e-5)
    # the Gauss-Newton curvature knows every scale at once: far fewer rollouts (counting
    # Levenberg-Marquardt's value-only trials too)
    assert len(lm_calls) < len(lbfgs_calls) / 2, (len(lm_calls), len(lbfgs_calls))


def test_gauss_newton_matrix_is_the_exact_curvature_where_predictions_are_linear(tmp_path):
    """Without drag the positions are linear in the launch velocity (a normal prior, so the
    unconstrained space is the velocity itself): J^T J plus the prior's Hessian is then the
    exact negative Hessian, and the value and gradient are the log density's own."""
    import jax

    from physdsl.compile import compile as compile_phys
    from physdsl.infer.base import gauss_newton_fn
    from physdsl.infer.problem import model_problem

    from .conftest import PROJECTILE_NOISE, PROJECTILE_TIMES, projectile_text, simulated_scene

    text = "\n".join(ln for ln in projectile_text().splitlines() if "linear_drag" not in ln)
    scene = simulated_scene(tmp_path, text, {"ball.velocity": np.array([3.2, 0.4, 4.3])},
                            PROJECTILE_TIMES, PROJECTILE_NOISE, seed=5)
    problem = model_problem(compile_phys(scene))
    x = np.array([2.0, -0.5, 5.0])
    v, g, H = (np.asarray(a) for a in gauss_newton_fn(problem)(jnp.asarray(x)))
    v_ref, g_ref = jax.value_and_grad(problem.logdensity)(jnp.asarray(x), problem.data)
    np.testing.assert_allclose(v, float(v_ref), rtol=1e-12)
    np.testing.assert_allclose(g, np.asarray(g_ref), rtol=1e-9, atol=1e-9)
    h = 1e-4
    fd = np.stack([(np.asarray(jax.grad(problem.logdensity)(jnp.asarray(x + h * e), problem.data))
                    - np.asarray(jax.grad(problem.logdensity)(jnp.asarray(x - h * e), problem.data)))
                   / (2 * h) for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(H, -fd, rtol=1e-6)
    assert np.linalg.eigvalsh(H).min() > 0


def _kinked(x):
    """A log density whose Gauss-Newton model never comes true: each damped step gains about
    1e-7 nats while the full step is predicted to gain 0.05 (the friction block's fit)."""
    x = np.asarray(x, dtype=float)
    return -1e-7 * float(np.sum(np.abs(x - 5.0))), 1e-1 * np.ones(1), 0.1 * np.eye(1)


def test_a_search_whose_steps_gain_nothing_that_matters_stops_as_stalled():
    """Five steps each gaining under ``STALL_GAIN`` far less than the model predicted end the
    search (done), long before its budget; more gains at that scale would change no figure
    derived from it."""
    from physdsl.infer import levenberg_marquardt as lm

    def gn(x):
        calls.append(1)
        return _kinked(x)

    calls: list = []
    state = lm.init(gn, np.zeros(1))
    while not state.done and state.steps < 300:
        state = lm.step(gn, state, lambda x: _kinked(x)[0])
    assert state.done and state.steps == lm.STALL
    assert lm.newton_gain(state.H, state.grad) > 1e3 * lm.GAIN_TOL  # not a converged mode
    assert len(calls) < 20


def test_tiny_gains_the_model_predicts_are_not_a_stall():
    """A search that starts under a heavy damping (after refusals at a kink, say) gains
    little at first, but as the quadratic model predicts (rho = 1): its damping falls
    threefold a step and it goes on to the mode, 0.1 nat above its start."""
    from physdsl.infer import levenberg_marquardt as lm

    def gn(x):
        x = np.asarray(x, dtype=float)
        return -0.5 * float(x @ x), -x, np.eye(1)

    state = lm.init(gn, np.array([np.sqrt(0.2)]))._replace(lam=1e9)
    first = []
    while not state.done and state.steps < 300:
        state = lm.step(gn, state, lambda x: gn(x)[0])
        first.append(state.value)
    assert first[1] - first[0] < lm.STALL_GAIN  # its first steps gain less than a stall's
    assert abs(state.x[0]) < 1e-4 and state.value > -1e-8  # yet it reached the mode
