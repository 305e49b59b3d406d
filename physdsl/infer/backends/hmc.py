"""HMC and NUTS from blackjax, tuned by blackjax's window adaptation (step size, diagonal mass)."""
from __future__ import annotations

import blackjax
import jax
import jax.numpy as jnp

from ..base import Backend, register_backend


class _BlackjaxHMCFamily(Backend):
    algorithm = None

    def _extra(self, settings):
        return {}

    def warmup(self, problem, positions, key, settings):
        adapt = blackjax.window_adaptation(self.algorithm, problem.logdensity,
                                           target_acceptance_rate=settings.target_accept,
                                           **self._extra(settings))

        def one(k, x):
            (state, params), _ = adapt.run(k, x, num_steps=settings.warmup)
            return state, params

        keys = jax.random.split(key, positions.shape[0])
        states, params = jax.jit(jax.vmap(one))(keys, positions)
        params = {k: params[k] for k in ("step_size", "inverse_mass_matrix")}
        return states, params, {"step_size": params["step_size"]}

    def sample(self, problem, states, params, key, n, settings):
        extra = self._extra(settings)

        def chain(k, state, p):
            kernel = self.algorithm(problem.logdensity, **p, **extra)

            def body(s, kk):
                s, info = kernel.step(kk, s)
                return s, (s.position, _stats(info))

            return jax.lax.scan(body, state, jax.random.split(k, n))

        keys = jax.random.split(key, states.position.shape[0])
        states, (draws, stats) = _jit_vmap(chain)(keys, states, params)
        return states, draws, stats


def _stats(info):
    return {
        "acceptance_rate": info.acceptance_rate,
        "diverging": info.is_divergent,
        "n_steps": getattr(info, "num_integration_steps", jnp.asarray(0)),
        "energy": getattr(info, "energy", jnp.asarray(0.0)),
    }


def _jit_vmap(fn):
    return jax.jit(jax.vmap(fn))


@register_backend
class NUTS(_BlackjaxHMCFamily):
    """blackjax NUTS: the default gradient-based sampler."""

    name = "nuts"
    algorithm = blackjax.nuts

    def _extra(self, settings):
        return {"max_num_doublings": settings.max_tree_depth}


@register_backend
class HMC(_BlackjaxHMCFamily):
    """blackjax HMC with a fixed number of leapfrog steps per draw."""

    name = "hmc"
    algorithm = blackjax.hmc

    def _extra(self, settings):
        return {"num_integration_steps": settings.integration_steps}
