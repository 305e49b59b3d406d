"""From a compiled Model to a Problem: numpyro's potential in unconstrained space, flattened."""
from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree
from numpyro.infer.util import initialize_model
from numpyro.infer.initialization import init_to_sample

from ..errors import InferenceError
from .base import Problem, safe_logdensity


def make_problem(model, key, chains: int):
    """Return (Problem, initial flat positions (chains, dim)) drawn from the prior.

    numpyro's ``initialize_model`` gives the potential (negative log joint) in unconstrained
    space and the map back to constrained values; each chain starts from its own prior draw
    at which the log density is finite.
    """
    discrete = [u.name for u in model.unknowns if u.discrete]
    if discrete:
        raise InferenceError(f"discrete unknowns ({', '.join(discrete)}) are not supported by "
                             "trajectory inference yet",
                             hint="give them a value, or fit shape from images with "
                                  "physdsl.render.inverse (Metropolis-within-Gibbs)")
    try:
        info, potential_fn, postprocess_fn, _ = initialize_model(
            jax.random.split(key, chains), model.numpyro_model, init_strategy=init_to_sample,
            dynamic_args=False)
    except RuntimeError as err:
        raise InferenceError("no prior draw gives a finite likelihood",
                             hint="check priors and units; the model may blow up at every "
                                  f"draw ({err})") from None
    z = info.z
    one = jax.tree_util.tree_map(lambda a: a[0], z)
    _, unravel = ravel_pytree(one)
    positions = jax.vmap(lambda t: ravel_pytree(t)[0])(z)

    def logdensity(x):
        return -potential_fn(unravel(x))

    def to_constrained(x):
        return postprocess_fn(unravel(x))

    problem = Problem(safe_logdensity(logdensity), to_constrained, int(positions.shape[1]), model, {})
    return problem, positions

