"""The Problem's value and gradient (forward mode read off the log density's jaxpr, the rollout's
loops taking those tangents directly) equal JAX's reverse mode through the rollout's own
forward-mode rule, and central finite differences (float64)."""
from __future__ import annotations

import jax
import numpy as np


def test_value_and_gradient_match_reverse_mode_and_finite_differences(projectile_model):
    from physdsl.infer.base import value_and_grad_fn
    from physdsl.infer.problem import make_problem

    problem, positions = make_problem(projectile_model, jax.random.PRNGKey(5), 2)
    vg = value_and_grad_fn(problem)
    raw = problem.logdensity.fun  # without safe_logdensity's custom rule: JAX's reverse mode
    ref = jax.jit(jax.value_and_grad(raw))
    for x in np.asarray(positions):
        v, g = vg(x)
        rv, rg = ref(x, problem.data)
        np.testing.assert_allclose(v, rv, rtol=1e-13)
        np.testing.assert_allclose(g, rg, rtol=1e-9, atol=1e-9 * np.max(np.abs(rg)))
        h = 1e-6
        fd = [(float(problem.logdensity(x + h * e, problem.data))
               - float(problem.logdensity(x - h * e, problem.data))) / (2 * h)
              for e in np.eye(x.size)]
        np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-5 * np.max(np.abs(fd)))
