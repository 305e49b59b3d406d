"""numpyro's NUTS through its functional kernel (``numpyro.infer.hmc.hmc``), on the same potential.

Used as a peer of blackjax NUTS (benchmarks, cross-checks). Warmup runs numpyro's own
adaptation (dual averaging + diagonal mass matrix) for ``settings.warmup`` iterations.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from numpyro.infer.hmc import hmc

from ..base import Backend, register_backend


@register_backend
class NumpyroNUTS(Backend):
    name = "numpyro-nuts"

    def _kernels(self, problem, settings):
        potential = lambda x: -problem.logdensity(x)  # noqa: E731
        return hmc(potential_fn=potential, algo="NUTS")

    def warmup(self, problem, positions, key, settings):
        init_kernel, sample_kernel = self._kernels(problem, settings)

        def chain(k, x):
            k0, k1 = jax.random.split(k)
            state = init_kernel(x, num_warmup=settings.warmup, target_accept_prob=settings.target_accept,
                                max_tree_depth=settings.max_tree_depth, rng_key=k0)
            state = jax.lax.fori_loop(0, settings.warmup, lambda i, s: sample_kernel(s), state)
            return state

        keys = jax.random.split(key, positions.shape[0])
        states = jax.jit(jax.vmap(chain))(keys, positions)
        return states, {}, {"step_size": states.adapt_state.step_size}

    def sample(self, problem, states, params, key, n, settings):
        init_kernel, sample_kernel = self._kernels(problem, settings)
        # numpyro's kernel needs its static settings registered by init_kernel once.
        init_kernel(jnp.zeros(problem.dim), num_warmup=0, max_tree_depth=settings.max_tree_depth)

        def chain(state):
            def body(s, _):
                s = sample_kernel(s)
                return s, (s.z, {"acceptance_rate": s.mean_accept_prob, "diverging": s.diverging,
                                 "n_steps": s.num_steps})
            return jax.lax.scan(body, state, None, length=n)

        states, (draws, stats) = jax.jit(jax.vmap(chain))(states)
        return states, draws, stats
