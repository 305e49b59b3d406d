"""HMC and NUTS from blackjax, tuned by Stan's window adaptation (step size, mass matrix:
dense by default, diagonal with ``Settings.dense_mass=False``).

Warmup and sampling run the same compiled block (``physdsl.infer.blocks``): up to
``settings.block`` transitions of every chain per call, chains vmapped, with the step size
and inverse mass matrix in each chain's carry. During warmup each transition also updates the
window adaptation (blackjax's ``window_adaptation.base``, schedule passed in per block);
sampling uses the adapted values. One compile serves both stages, every block and every
Model of the scene's structure.
"""
from __future__ import annotations

import warnings

import blackjax
import jax
import jax.numpy as jnp
import numpy as np
from blackjax.adaptation.window_adaptation import base as window_base
from blackjax.adaptation.window_adaptation import build_schedule
from blackjax.mcmc.hmc import HMCState

from ..base import Backend, bind, register_backend, value_and_grad_fn
from ..blocks import block_runner, run_blocks

INITIAL_STEP_SIZE = 1.0


def initial_states(problem, positions) -> HMCState:
    """HMC states at ``positions`` from the Problem's one compiled value-and-gradient."""
    vg = value_and_grad_fn(problem)
    pairs = [vg(x) for x in jnp.asarray(positions)]
    return HMCState(jnp.asarray(positions), jnp.stack([v for v, _ in pairs]),
                    jnp.stack([g for _, g in pairs]))


def tree_where(cond, a, b):
    """``a`` where ``cond`` (a scalar) else ``b``, leaf by leaf."""
    return jax.tree_util.tree_map(lambda x, y: jnp.where(cond, x, y), a, b)


def _window(settings):
    with warnings.catch_warnings():  # base() is blackjax's documented building block
        warnings.simplefilter("ignore", DeprecationWarning)
        return window_base(not settings.dense_mass, target_acceptance_rate=settings.target_accept)


class _BlackjaxHMCFamily(Backend):
    algorithm = None
    step_jitter = 0.0  # relative half-width of a uniform jitter of the step size per transition

    def _extra(self, settings) -> dict:
        return {}

    def _runner(self, problem, settings):
        """The compiled block: carry (state, adaptation state, (step size, inverse mass));
        shared (stages (block, 2), adapting)."""
        extra = self._extra(settings)
        _, update, _ = _window(settings)

        def transition(data, key, carry, shared, i):
            state, astate, (step_size, imm) = carry
            stages, adapting = shared
            step_size = jnp.where(adapting, astate.step_size, step_size)
            imm = jnp.where(adapting, astate.inverse_mass_matrix, imm)
            if self.step_jitter:
                u = jax.random.uniform(jax.random.fold_in(key, 1), minval=-1.0, maxval=1.0)
                step_size = step_size * (1.0 + self.step_jitter * u)
            state, info = self.algorithm(bind(problem, data), step_size, imm, **extra).step(key, state)
            new = update(astate, (stages[i, 0], stages[i, 1]), state.position, info.acceptance_rate)
            astate = tree_where(adapting, new, astate)
            return (state, astate, carry[2]), (state.position, _stats(info))

        key = (self.name, tuple(sorted(extra.items())), settings.target_accept, settings.dense_mass)
        return block_runner(problem, key, transition, settings.block)

    def warmup(self, problem, positions, key, settings, on_block=None):
        init, _, final = _window(settings)
        run = self._runner(problem, settings)
        positions = jnp.asarray(positions)
        chains = positions.shape[0]
        astates = jax.vmap(lambda x: init(x, INITIAL_STEP_SIZE))(positions)
        tuning = (jnp.ones(chains), astates.inverse_mass_matrix)  # placeholders while adapting
        carries = (initial_states(problem, positions), astates, tuning)
        n = settings.warmup
        schedule = np.asarray(build_schedule(n), dtype=np.int32).reshape(n, 2)

        def shared(start, m):
            stages = np.zeros((settings.block, 2), np.int32)
            stages[:m] = schedule[start:start + m]
            return jnp.asarray(stages), jnp.asarray(True)

        (states, astates, _), _ = run_blocks(run, problem, key, carries, n, settings.block, shared,
                                             on_block)
        step_size, inverse_mass_matrix = jax.vmap(final)(astates)
        params = {"step_size": step_size, "inverse_mass_matrix": inverse_mass_matrix}
        return states, params, {"step_size": step_size}

    def sample(self, problem, states, params, key, n, settings, start=0):
        init, _, _ = _window(settings)
        run = self._runner(problem, settings)
        states = HMCState(*map(jnp.asarray, states))
        step_size = jnp.asarray(params["step_size"])
        imm = jnp.asarray(params["inverse_mass_matrix"])
        carries = (states, jax.vmap(lambda x: init(x, INITIAL_STEP_SIZE))(states.position),
                   (step_size, imm))
        shared = (jnp.zeros((settings.block, 2), jnp.int32), jnp.asarray(False))
        (states, _, _), (draws, stats) = run_blocks(run, problem, key, carries, n, settings.block,
                                                    lambda _, m: shared, offset=start)
        return states, draws, stats


def _stats(info):
    return {
        "acceptance_rate": info.acceptance_rate,
        "diverging": info.is_divergent,
        "n_steps": getattr(info, "num_integration_steps", 0),
        "energy": getattr(info, "energy", 0.0),
    }


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
    # a fixed trajectory length can resonate with a period of the posterior (a chain then
    # zig-zags along one direction and r-hat stays high); jittering the step size by +-20%
    # per transition breaks it (Neal 2011, section 5.4.2.2)
    step_jitter = 0.2

    def _extra(self, settings):
        return {"num_integration_steps": settings.integration_steps}
