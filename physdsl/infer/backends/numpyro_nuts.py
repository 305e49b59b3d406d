"""numpyro's NUTS through its functional kernel (``numpyro.infer.hmc.hmc``), on the same potential.

Used as a peer of blackjax NUTS (benchmarks, cross-checks). numpyro's ``sample_kernel``
adapts (dual averaging + diagonal mass matrix) while its iteration count is below
``settings.warmup`` and samples after, so one jitted transition of one chain serves both
stages, driven from Python chain by chain. Chains start from states built with the Problem's compiled value-and-gradient
(``ParamInfo``), so initialisation compiles nothing else.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer.hmc import hmc
from numpyro.infer.util import ParamInfo

from ..base import Backend, cached, register_backend, value_and_grad_fn
from .hmc import stack, unstack


def _kernels(problem, settings):
    """(init, jitted sample_kernel) for these settings, made once per Problem."""
    def build():
        logdensity = problem.logdensity
        init_kernel, sample_kernel = hmc(potential_fn=lambda x: -logdensity(x), algo="NUTS")

        def init(x, pe, grad, key):
            return init_kernel(ParamInfo(x, pe, grad), num_warmup=settings.warmup,
                               target_accept_prob=settings.target_accept,
                               max_tree_depth=settings.max_tree_depth, rng_key=key)

        # registers the kernel's static settings (needed when resuming without a warmup)
        jax.eval_shape(init, jnp.zeros(problem.dim), jnp.zeros(()), jnp.zeros(problem.dim),
                       jax.random.PRNGKey(0))
        return init, jax.jit(sample_kernel)

    key = ("numpyro-nuts", settings.warmup, settings.target_accept, settings.max_tree_depth)
    return cached(problem, key, build)


@register_backend
class NumpyroNUTS(Backend):
    name = "numpyro-nuts"

    def warmup(self, problem, positions, key, settings):
        init, step = _kernels(problem, settings)
        vg = value_and_grad_fn(problem)
        states = []
        for x, k in zip(jnp.asarray(positions), jax.random.split(key, positions.shape[0])):
            v, g = vg(x)
            states.append(init(x, -v, -g, k))
        for _ in range(settings.warmup):
            states = [step(s) for s in states]
        states = stack(states)
        return states, {}, {"step_size": states.adapt_state.step_size}

    def sample(self, problem, states, params, key, n, settings):
        _, step = _kernels(problem, settings)
        states = unstack(states, np.shape(states.z)[0])
        draws, stats = [], []
        for _ in range(n):
            states = [step(s) for s in states]
            draws.append(np.stack([np.asarray(s.z) for s in states]))
            stats.append({"acceptance_rate": np.stack([np.asarray(s.accept_prob) for s in states]),
                          "diverging": np.stack([np.asarray(s.diverging) for s in states]),
                          "n_steps": np.stack([np.asarray(s.num_steps) for s in states])})
        return stack(states), np.stack(draws, axis=1), {k: np.stack([s[k] for s in stats], axis=1)
                                                        for k in stats[0]}
