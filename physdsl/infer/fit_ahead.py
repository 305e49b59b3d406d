"""A fit's programs, compiled ahead (``physdsl.ahead``): queued for the background thread in
the order the fit needs them, so each compiles while the fit does something else.

The rollout that the posterior pass and the fit's quality read, then the Gauss-Newton program
(which the fit calls first, and compiles itself if the rollout is still compiling); where the
fit makes its own starts, their small programs (the prior's centre, the start from the data):
the fit waits for the Gauss-Newton program before it makes its starts, and meanwhile compiles
those, queued behind it, itself (the pendulum's ``infer``, no cache: 15.0 -> 12.9 s to its
first optimisation); where it makes robust intervals, the contact law's rollout
(``contact_law``), which compiles while the fit searches for its modes.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from numpyro.infer.util import constrain_fn

from . import contact_law
from .data_starts import data_start_ahead
from .multistart import CENTRE_DRAWS
from .problem import prior_draws_ahead, unconstrained_layout, unraveler


def compile_ahead(problem, starts: bool = True, robust: bool = False) -> None:
    """Queue ``problem``'s fit programs (the module's docstring); ``starts``: the fit makes its
    own starts; ``robust``: it makes robust intervals. Nothing without a Gauss-Newton program."""
    if problem.gauss_newton is None:
        return
    model = problem.model
    x = jax.ShapeDtypeStruct((problem.dim,), jnp.result_type(float))
    unravel, _ = unraveler(unconstrained_layout(model))
    values = jax.eval_shape(lambda x: constrain_fn(model.prior_values, (), {}, unravel(x)), x)
    model.fit_simulate_ahead(values)
    problem.gauss_newton.ahead(x, problem.data)
    if starts:
        prior_draws_ahead(problem, CENTRE_DRAWS)
        data_start_ahead(problem)
    if robust:
        contact_law.residuals_ahead(model, problem)


__all__ = ["compile_ahead"]
