"""A run can start its first chain at given constrained values (a refit of a nested model)."""
import jax
import numpy as np

from physdsl.infer.problem import initial_positions, model_problem


def test_first_chain_starts_at_the_given_values(projectile_model):
    problem = model_problem(projectile_model)
    start = {"linear_drag@ball.coefficient": 0.123, "ball.velocity": [3.0, 0.1, 4.0]}
    x = initial_positions(problem, jax.random.PRNGKey(0), 2, start)
    values = problem.to_constrained(x[0], problem.data)
    np.testing.assert_allclose(values["linear_drag@ball.coefficient"], 0.123, rtol=1e-12)
    np.testing.assert_allclose(values["ball.velocity"], [3.0, 0.1, 4.0], rtol=1e-12)
    other = problem.to_constrained(x[1], problem.data)  # the second chain: a prior draw
    assert not np.allclose(other["ball.velocity"], [3.0, 0.1, 4.0])


def test_a_start_outside_the_support_falls_back_to_the_prior(projectile_model):
    problem = model_problem(projectile_model)
    x = initial_positions(problem, jax.random.PRNGKey(0), 2,
                          {"linear_drag@ball.coefficient": -1.0})  # half-normal: must be > 0
    for xi in x:
        assert problem.to_constrained(xi, problem.data)["linear_drag@ball.coefficient"] > 0


def test_a_scalar_start_fills_a_vector_unknown(projectile_model):
    problem = model_problem(projectile_model)
    x = initial_positions(problem, jax.random.PRNGKey(0), 1, {"ball.velocity": 3.5})
    np.testing.assert_allclose(problem.to_constrained(x[0], problem.data)["ball.velocity"], 3.5)
