"""HMC and NUTS from blackjax, tuned by Stan's window adaptation (step size, mass matrix:
dense by default, diagonal with ``Settings.dense_mass=False``).

Both run in the Laplace frame (``physdsl.infer.precondition``): x = shift + scale z, with the
posterior near a standard normal in z, so the adaptation starts from unit widths.
Warmup and sampling run the same compiled block (``physdsl.infer.blocks``): up to
``settings.block`` transitions of every chain per call (``blocks.chains_side_by_side``), with
the step size, inverse mass matrix and frame in each chain's carry. During warmup each
transition also updates the
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
from ..precondition import from_frame, laplace_frame, to_frame

INITIAL_STEP_SIZE = 1.0


def values_and_grads(problem, positions):
    """(log densities, gradients) at ``positions`` from the Problem's one compiled
    value-and-gradient."""
    vg = value_and_grad_fn(problem)
    pairs = [vg(x) for x in jnp.asarray(positions)]
    return jnp.stack([v for v, _ in pairs]), jnp.stack([g for _, g in pairs])


def initial_states(positions, values, grads, shift, scale) -> HMCState:
    """HMC states at ``positions`` (their log densities and gradients), in the frame
    x = shift + scale z (the gradient in z is scale^T times the gradient in x)."""
    return HMCState(to_frame(shift, scale, positions), values, grads @ jnp.asarray(scale))


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
        """The compiled block: carry (state in the frame, adaptation state, (step size,
        inverse mass, shift, scale)); shared (stages (block, 2), adapting). It emits draws in
        the problem's own coordinates."""
        extra = self._extra(settings)
        _, update, _ = _window(settings)

        def transition(data, key, carry, shared, i):
            state, astate, (step_size, imm, shift, scale) = carry
            stages, adapting = shared
            step_size = jnp.where(adapting, astate.step_size, step_size)
            imm = jnp.where(adapting, astate.inverse_mass_matrix, imm)
            if self.step_jitter:
                u = jax.random.uniform(jax.random.fold_in(key, 1), minval=-1.0, maxval=1.0)
                step_size = step_size * (1.0 + self.step_jitter * u)
            logdensity = bind(problem, data)
            state, info = self.algorithm(lambda z: logdensity(from_frame(shift, scale, z)),
                                         step_size, imm, **extra).step(key, state)
            new = update(astate, (stages[i, 0], stages[i, 1]), state.position, info.acceptance_rate)
            astate = tree_where(adapting, new, astate)
            draw = from_frame(shift, scale, state.position)
            return (state, astate, carry[2]), (draw, _stats(info))

        key = (self.name, tuple(sorted(extra.items())), settings.target_accept, settings.dense_mass)
        return block_runner(problem, key, transition, settings.block)

    def warmup(self, problem, positions, key, settings, on_block=None):
        init, _, final = _window(settings)
        run = self._runner(problem, settings)
        positions = jnp.asarray(positions)
        chains = positions.shape[0]
        values, grads = values_and_grads(problem, positions)
        shift, scale = (jnp.asarray(a) for a in laplace_frame(problem, positions, values))
        states = initial_states(positions, values, grads, shift, scale)
        astates = jax.vmap(lambda z: init(z, INITIAL_STEP_SIZE))(states.position)
        frame = (jnp.broadcast_to(shift, positions.shape),
                 jnp.broadcast_to(scale, (chains, *scale.shape)))
        # step size and inverse mass: placeholders while adapting
        tuning = (jnp.ones(chains), astates.inverse_mass_matrix, *frame)
        carries = (states, astates, tuning)
        n = settings.warmup
        schedule = np.asarray(build_schedule(n), dtype=np.int32).reshape(n, 2)

        def shared(start, m):
            stages = np.zeros((settings.block, 2), np.int32)
            stages[:m] = schedule[start:start + m]
            return jnp.asarray(stages), jnp.asarray(True)

        (states, astates, _), _ = run_blocks(run, problem, key, carries, n, settings.block, shared,
                                             on_block)
        step_size, inverse_mass_matrix = jax.vmap(final)(astates)
        params = {"step_size": step_size, "inverse_mass_matrix": inverse_mass_matrix,
                  "shift": frame[0], "scale": frame[1]}
        return states, params, {"step_size": step_size}

    def sample(self, problem, states, params, key, n, settings, start=0):
        init, _, _ = _window(settings)
        run = self._runner(problem, settings)
        states = HMCState(*map(jnp.asarray, states))
        chains, dim = states.position.shape
        frame = (params.get("shift", np.zeros((chains, dim))),  # a run saved before frames
                 params.get("scale", np.broadcast_to(np.eye(dim), (chains, dim, dim))))
        tuning = tuple(jnp.asarray(a) for a in
                       (params["step_size"], params["inverse_mass_matrix"], *frame))
        carries = (states, jax.vmap(lambda z: init(z, INITIAL_STEP_SIZE))(states.position),
                   tuning)
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
