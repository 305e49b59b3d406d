"""Random-walk Metropolis-Hastings (blackjax) with an adapted Gaussian proposal.

Warmup adapts a Gaussian proposal: its shape from the running covariance of the chain
(adaptive Metropolis, so correlated posteriors mix) and its overall scale by Robbins-Monro
towards the optimal acceptance rate 0.234 (Roberts & Rosenthal). Needs no gradient (only the
log density's value is evaluated), so it also runs on rollouts that are not differentiable.
As for HMC, warmup and sampling run one compiled block of transitions
(``physdsl.infer.blocks``); a flag says whether the proposal adapts.
"""
from __future__ import annotations

import blackjax
import jax
import jax.numpy as jnp
from blackjax.mcmc.random_walk import RWState

from ..base import Backend, bind, register_backend, value_and_grad_fn
from ..blocks import block_runner, run_blocks
from .hmc import tree_where

TARGET_ACCEPT = 0.234


def _adapt(i, log_scale, mean, cov, position, acc):
    """One update of a chain's proposal: Robbins-Monro on the log scale, running mean and
    covariance of the chain (adaptive Metropolis, Haario et al.); returns the new Cholesky
    factor of the proposal too."""
    acc = jnp.where(jnp.isfinite(acc), jnp.minimum(acc, 1.0), 0.0)
    log_scale = log_scale + (acc - TARGET_ACCEPT) / jnp.sqrt(i + 1.0)
    w = 1.0 / (i + 10.0)
    delta = position - mean
    cov = (1 - w) * cov + w * jnp.outer(delta, delta)
    return log_scale, mean + w * delta, cov, _sigma(log_scale, cov)


def _sigma(log_scale, cov):
    """Proposal 'standard deviation' matrix: scale x 2.38/sqrt(d) x chol(cov)."""
    d = cov.shape[-1]
    jitter = 1e-10 * (jnp.trace(cov) / d + 1e-12) * jnp.eye(d)
    return jnp.exp(log_scale) * 2.38 / jnp.sqrt(d) * jnp.linalg.cholesky(cov + jitter)


def _transition(problem):
    """One step of one chain; carry (state, (log scale, mean, cov), sigma); shared (offset,
    adapting): the transition's index in warmup is offset + i."""
    def transition(data, key, carry, shared, i):
        state, moments, sigma = carry
        offset, adapting = shared
        state, info = blackjax.normal_random_walk(bind(problem, data), sigma).step(key, state)
        *new_moments, new_sigma = _adapt((offset + i).astype(float), *moments, state.position,
                                         info.acceptance_rate)
        moments, sigma = tree_where(adapting, (tuple(new_moments), new_sigma), (moments, sigma))
        out = (state.position, {"acceptance_rate": info.acceptance_rate,
                                "nonfinite": ~jnp.isfinite(state.logdensity)})
        return (state, moments, sigma), out
    return transition


@register_backend
class RMH(Backend):
    name = "rmh"
    uses_gradient = False

    def _runner(self, problem, settings):
        return block_runner(problem, "rmh", _transition(problem), settings.block)

    def warmup(self, problem, positions, key, settings, on_block=None):
        positions = jnp.asarray(positions)
        chains, dim = positions.shape
        vg = value_and_grad_fn(problem)  # compiled already for the starts
        states = RWState(positions, jnp.stack([vg(x)[0] for x in positions]))
        moments = (jnp.zeros(chains), positions, jnp.broadcast_to(0.01 * jnp.eye(dim), (chains, dim, dim)))
        carries = (states, moments, jax.vmap(_sigma)(moments[0], moments[2]))
        (states, _, sigma), _ = run_blocks(
            self._runner(problem, settings), problem, key, carries, max(settings.warmup, 1),
            settings.block, lambda start, m: (jnp.asarray(start), jnp.asarray(True)), on_block)
        return states, {"sigma": sigma}, {"proposal_sigma": sigma}

    def sample(self, problem, states, params, key, n, settings, start=0):
        states = RWState(*map(jnp.asarray, states))
        sigma = jnp.asarray(params["sigma"])
        chains, dim = states.position.shape
        moments = (jnp.zeros(chains), states.position, jnp.broadcast_to(jnp.eye(dim), (chains, dim, dim)))
        (states, _, _), (draws, stats) = run_blocks(
            self._runner(problem, settings), problem, key, (states, moments, sigma), n,
            settings.block, lambda _, m: (jnp.asarray(0), jnp.asarray(False)), offset=start)
        return states, draws, stats
