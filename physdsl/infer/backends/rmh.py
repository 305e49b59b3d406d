"""Random-walk Metropolis-Hastings (blackjax) with an adapted Gaussian proposal.

Warmup adapts a diagonal proposal: its shape from the running variance of the chain and its
overall scale by Robbins-Monro towards the optimal acceptance rate 0.234 (Roberts & Rosenthal).
Needs no gradient, so it also runs on rollouts that are not differentiable.
"""
from __future__ import annotations

import blackjax
import jax
import jax.numpy as jnp

from ..base import Backend, register_backend

TARGET_ACCEPT = 0.234


def _step(problem, state, key, sigma):
    kernel = blackjax.normal_random_walk(problem.logdensity, sigma)
    return kernel.step(key, state)


@register_backend
class RMH(Backend):
    name = "rmh"
    uses_gradient = False

    def warmup(self, problem, positions, key, settings):
        dim = positions.shape[1]
        n = max(settings.warmup, 1)

        def chain(k, x):
            state = blackjax.normal_random_walk(problem.logdensity, jnp.ones(dim)).init(x)

            def body(carry, inp):
                state, log_scale, mean, var = carry
                i, kk = inp
                sigma = jnp.exp(log_scale) * jnp.sqrt(var) * 2.38 / jnp.sqrt(dim)
                state, info = _step(problem, state, kk, sigma)
                acc = jnp.where(jnp.isfinite(info.acceptance_rate), info.acceptance_rate, 0.0)
                gain = 1.0 / jnp.sqrt(i + 1.0)
                log_scale = log_scale + gain * (jnp.minimum(acc, 1.0) - TARGET_ACCEPT)
                w = 1.0 / (i + 10.0)
                delta = state.position - mean
                mean = mean + w * delta
                var = jnp.clip((1 - w) * var + w * delta**2, 1e-12, 1e6)
                return (state, log_scale, mean, var), acc

            init_var = jnp.full(dim, 0.01)
            carry0 = (state, jnp.asarray(0.0), x, init_var)
            (state, log_scale, _, var), acc = jax.lax.scan(
                body, carry0, (jnp.arange(n, dtype=float), jax.random.split(k, n)))
            sigma = jnp.exp(log_scale) * jnp.sqrt(var) * 2.38 / jnp.sqrt(dim)
            return state, {"sigma": sigma}

        keys = jax.random.split(key, positions.shape[0])
        states, params = jax.jit(jax.vmap(chain))(keys, positions)
        return states, params, {"proposal_sigma": params["sigma"]}

    def sample(self, problem, states, params, key, n, settings):
        def chain(k, state, p):
            def body(s, kk):
                s, info = _step(problem, s, kk, p["sigma"])
                return s, (s.position, {"acceptance_rate": info.acceptance_rate,
                                        "nonfinite": ~jnp.isfinite(s.logdensity)})

            return jax.lax.scan(body, state, jax.random.split(k, n))

        keys = jax.random.split(key, states.position.shape[0])
        states, (draws, stats) = jax.jit(jax.vmap(chain))(keys, states, params)
        return states, draws, stats
