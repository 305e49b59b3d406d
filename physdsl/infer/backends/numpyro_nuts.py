"""numpyro's NUTS through its functional kernel (``numpyro.infer.hmc.hmc``), on the same potential.

Used as a peer of blackjax NUTS (benchmarks, cross-checks). numpyro's ``sample_kernel``
adapts (dual averaging + mass matrix, dense unless ``Settings.dense_mass`` is off) while its iteration count is below
``settings.warmup`` and samples after, so one compiled block of transitions
(``physdsl.infer.blocks``: chains vmapped on an accelerator, a thread a chain on the CPU;
the data passed as the kernel's model argument)
serves both stages. Chains start from states built with the Problem's compiled
value-and-gradient (``ParamInfo``), so initialisation compiles nothing else.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from numpyro.infer.hmc import hmc
from numpyro.infer.util import ParamInfo

from ..base import Backend, cached, register_backend, value_and_grad_fn
from ..blocks import block_runner, run_blocks


def _kernels(problem, settings):
    """(init, sample_kernel) for these settings, made once per Problem structure."""
    def build():
        logdensity = problem.logdensity
        init_kernel, sample_kernel = hmc(
            potential_fn_gen=lambda data: (lambda x: -logdensity(x, data)), algo="NUTS")

        def init(x, pe, grad, key, data):
            return init_kernel(ParamInfo(x, pe, grad), num_warmup=settings.warmup,
                               target_accept_prob=settings.target_accept,
                               max_tree_depth=settings.max_tree_depth, rng_key=key,
                               dense_mass=settings.dense_mass,
                               model_args=(data,))

        # registers the kernel's static settings (needed when resuming without a warmup)
        jax.eval_shape(init, jnp.zeros(problem.dim), jnp.zeros(()), jnp.zeros(problem.dim),
                       jax.random.PRNGKey(0), problem.data)
        return init, sample_kernel

    key = ("numpyro-nuts", settings.warmup, settings.target_accept, settings.max_tree_depth,
           settings.dense_mass)
    return cached(problem, key, build)


def _runner(problem, settings):
    _, sample_kernel = _kernels(problem, settings)

    def transition(data, key, state, shared, i):
        state = sample_kernel(state, model_args=(data,))
        return state, (state.z, {"acceptance_rate": state.accept_prob,
                                 "diverging": state.diverging, "n_steps": state.num_steps})

    key = ("numpyro-nuts", settings.warmup, settings.target_accept, settings.max_tree_depth,
           settings.dense_mass)
    return block_runner(problem, key, transition, settings.block)


@register_backend
class NumpyroNUTS(Backend):
    name = "numpyro-nuts"

    def warmup(self, problem, positions, key, settings, on_block=None):
        init, _ = _kernels(problem, settings)
        vg = value_and_grad_fn(problem)
        states = []
        for x, k in zip(jnp.asarray(positions), jax.random.split(key, positions.shape[0])):
            v, g = vg(x)
            states.append(init(x, -v, -g, k, problem.data))
        states = jax.tree_util.tree_map(lambda *a: jnp.stack(a), *states)
        states, _ = run_blocks(_runner(problem, settings), problem, key, states, settings.warmup,
                               settings.block, on_block=on_block)
        return states, {}, {"step_size": states.adapt_state.step_size}

    def sample(self, problem, states, params, key, n, settings, start=0):
        states = jax.tree_util.tree_map(jnp.asarray, states)
        states, (draws, stats) = run_blocks(_runner(problem, settings), problem, key, states, n,
                                            settings.block, offset=start)
        return states, draws, stats
