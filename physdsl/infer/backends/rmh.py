"""Random-walk Metropolis-Hastings (blackjax) with an adapted Gaussian proposal.

Warmup adapts a Gaussian proposal: its shape from the running covariance of the chain
(adaptive Metropolis, so correlated posteriors mix) and its overall scale by Robbins-Monro
towards the optimal acceptance rate 0.234 (Roberts & Rosenthal). Needs no gradient (only the
log density's value is compiled), so it also runs on rollouts that are not differentiable. As for HMC, one transition of one chain (proposal scale as an argument)
is jitted once per Problem and driven from Python in warmup and sampling alike.
"""
from __future__ import annotations

import blackjax
import jax
import jax.numpy as jnp
import numpy as np
from blackjax.mcmc.random_walk import RWState

from ..base import Backend, cached, register_backend
from .hmc import chain_keys, stack, unstack

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


@register_backend
class RMH(Backend):
    name = "rmh"
    uses_gradient = False

    def _step(self, problem):
        def build():
            logdensity = problem.logdensity

            def one(k, state, sigma):
                return blackjax.normal_random_walk(logdensity, sigma).step(k, state)
            return jax.jit(one)
        return cached(problem, ("rmh", "step"), build)

    def warmup(self, problem, positions, key, settings):
        chains, dim = positions.shape
        step = self._step(problem)
        value = cached(problem, ("rmh", "value"), lambda: jax.jit(problem.logdensity))
        adapt = cached(problem, ("rmh", "adapt"), lambda: jax.jit(_adapt))
        positions = jnp.asarray(positions)
        states = [RWState(x, value(x)) for x in positions]
        moments = [(jnp.zeros(()), x, 0.01 * jnp.eye(dim)) for x in positions]
        sigmas = [_sigma(m[0], m[2]) for m in moments]
        n = max(settings.warmup, 1)
        for i, k in enumerate(chain_keys(key, n, chains)):
            for c in range(chains):
                states[c], info = step(k[c], states[c], sigmas[c])
                *moments[c], sigmas[c] = adapt(jnp.asarray(float(i)), *moments[c],
                                               states[c].position, info.acceptance_rate)
        sigma = jnp.stack(sigmas)
        return stack(states), {"sigma": sigma}, {"proposal_sigma": sigma}

    def sample(self, problem, states, params, key, n, settings):
        step = self._step(problem)
        chains = np.shape(params["sigma"])[0]
        states = unstack(RWState(*states), chains)
        draws, acc, nonfinite = [], [], []
        for k in chain_keys(key, n, chains):
            row_acc = []
            for c in range(chains):
                states[c], info = step(k[c], states[c], params["sigma"][c])
                row_acc.append(np.asarray(info.acceptance_rate))
            draws.append(np.stack([np.asarray(s.position) for s in states]))
            acc.append(np.stack(row_acc))
            nonfinite.append(~np.isfinite([float(s.logdensity) for s in states]))
        return stack(states), np.stack(draws, axis=1), {"acceptance_rate": np.stack(acc, axis=1),
                                                        "nonfinite": np.stack(nonfinite, axis=1)}
