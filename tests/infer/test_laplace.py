"""The Laplace step of the MAP backend: exact on a Gaussian, a clear error where it has no meaning."""
import jax.numpy as jnp
import numpy as np
import pytest

from physdsl.infer.backends.map import LaplaceError, laplace_sqrt
from physdsl.infer.base import Problem


def _problem(logdensity, dim):
    return Problem(lambda x, data: logdensity(x), None, dim, None, None, {})


def test_laplace_square_root_of_a_gaussian_is_its_covariance():
    cov = np.array([[2.0, 0.6, 0.0], [0.6, 1.0, -0.3], [0.0, -0.3, 0.5]])
    prec = jnp.asarray(np.linalg.inv(cov))
    s = laplace_sqrt(_problem(lambda x: -0.5 * x @ prec @ x, 3), np.zeros(3))
    assert np.allclose(s @ s.T, cov, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("curvature", [0.0, 1.0])  # flat (undetermined), curving up (a saddle)
def test_no_laplace_where_the_log_density_is_not_concave(curvature):
    problem = _problem(lambda x: -0.5 * x[0] ** 2 + 0.5 * curvature * x[1] ** 2, 2)
    with pytest.raises(LaplaceError, match="1 of 2 directions") as err:
        laplace_sqrt(problem, np.zeros(2))
    assert err.value.exit_code == 1 and "nuts" in err.value.render()


def test_a_chain_in_a_minor_basin_takes_the_best_mode():
    """Two basins, the one at x = -2 lower by 50 in log density: the chain that ends there
    takes the best mode's Laplace approximation (a negligible share of the posterior)."""
    import jax
    import jax.numpy as jnp

    from physdsl.infer.backends.map import MAP
    from physdsl.infer.base import Problem, Settings

    def logdensity(x, data):
        up = -0.5 * jnp.sum((x - 2.0) ** 2) / 0.1**2
        down = -0.5 * jnp.sum((x + 2.0) ** 2) / 0.3**2 - 50.0
        return jnp.where(x[0] > 0, up, down)

    problem = Problem(logdensity, lambda x, d: {"x": x}, 1, None, None, {})
    modes, params, info = MAP().warmup(problem, jnp.array([[1.0], [-1.0]]), jax.random.PRNGKey(0),
                                       Settings(warmup=100))
    np.testing.assert_allclose(np.asarray(modes)[:, 0], [2.0, 2.0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(params["chol"])[:, 0, 0], [0.1, 0.1], rtol=1e-4)


def test_major_modes_keeps_near_basins_and_replaces_minor_or_broken_ones():
    """Samplers start from ``major_modes``: a mode 5 below the best is kept (a real share of
    the posterior), one 50 below or with a non-finite density restarts at the best."""
    from physdsl.infer.backends.map import major_modes

    def logdensity(x, data):
        return jnp.where(x[0] > 5, jnp.nan, -0.5 * (x[0] - 1.0) ** 2 - jnp.where(x[0] < 0, 50.0, 0.0))

    problem = Problem(logdensity, None, 1, None, None, {})
    x = np.array([[1.0], [1.0 + np.sqrt(10.0)], [-1.0], [6.0]])  # best, 5 below, minor, NaN
    modes, lps, best = major_modes(problem, x)
    assert best == 0
    np.testing.assert_allclose(modes[:, 0], [1.0, 1.0 + np.sqrt(10.0), 1.0, 1.0])
    np.testing.assert_allclose(lps, [0.0, -5.0, 0.0, 0.0])


def test_a_kink_takes_the_gauss_newton_curvature():
    """At a kink of the residuals (as where Coulomb friction reverses in a rollout), central
    differences of the gradient curve the wrong way: a least-squares problem then takes its
    Gauss-Newton curvature J^T J (the data's Fisher information), which has no such artefact.
    Without the least-squares form the same point is an error, as before (sliding_block_01
    with its friction added: MAP fitted 1.005σ, mu 0.0602 vs 0.06, and failed its Laplace step
    along 0.89 mu + 0.45 v0, curvature -1.2e5)."""
    import jax

    from physdsl.infer.base import gauss_newton

    def with_residuals(x, data):
        r = jnp.array([10.0 * (x[0] - 1.0), 10.0 * x[1], 3.0 - 2.0 * jnp.abs(x[1])])
        return -0.5 * r @ r, r

    def logdensity(x, data):
        return with_residuals(x, data)[0]

    at = np.array([1.0, 0.0])
    plain = Problem(logdensity, None, 2, None, None, {})
    with pytest.raises(LaplaceError, match="1 of 2 directions"):
        laplace_sqrt(plain, at)
    least_squares = plain._replace(gauss_newton=gauss_newton(with_residuals),
                                   prior_hessian=lambda x: jnp.zeros((2, 2)), cache={})
    S = laplace_sqrt(least_squares, at)
    J = np.asarray(jax.jacfwd(lambda x: with_residuals(x, None)[1])(jnp.asarray(at)))
    assert np.allclose(S @ S.T, np.linalg.inv(J.T @ J), rtol=1e-10)


def test_a_direction_flat_in_the_data_too_is_still_an_error():
    """Only the sum x0 + x1 is measured: J^T J is singular too, so no curvature is made up."""
    from physdsl.infer.base import gauss_newton

    def with_residuals(x, data):
        r = jnp.array([10.0 * (x[0] + x[1] - 1.0)])
        return -0.5 * r @ r, r

    problem = Problem(lambda x, data: with_residuals(x, data)[0], None, 2, None, None, {},
                      gauss_newton=gauss_newton(with_residuals),
                      prior_hessian=lambda x: jnp.zeros((2, 2)))
    with pytest.raises(LaplaceError, match="1 of 2 directions"):
        laplace_sqrt(problem, np.array([0.5, 0.5]))


def test_laplace_normals_are_per_draw_and_compile_once_per_dimension():
    """Draw j of chain c comes from fold_in(split(key)[c], j), however the draws are cut into
    calls and whatever the chain count: the blocks give exactly the per-draw numbers, and one
    compiled program serves every chain and draw count of a dimension."""
    import jax

    from physdsl.infer.backends.map import _normal_block, _normals

    key = jax.random.PRNGKey(11)
    whole = _normals(key, 0, 3, 300, 5)
    split = np.concatenate([_normals(key, 0, 3, 120, 5), _normals(key, 120, 3, 180, 5)], axis=1)
    np.testing.assert_array_equal(whole, split)
    chain_keys = jax.random.split(key, 3)
    for c, j in ((0, 0), (1, 17), (2, 299)):
        one = jax.random.normal(jax.random.fold_in(chain_keys[c], j), (5,))
        np.testing.assert_array_equal(whole[c, j], np.asarray(one))
    before = _normal_block._cache_size()
    _normals(key, 7, 2, 40, 5)
    _normals(key, 0, 4, 250, 5)
    assert _normal_block._cache_size() == before
    assert abs(whole.mean()) < 0.1 and abs(whole.std() - 1) < 0.05
