"""HMC and NUTS from blackjax, tuned by Stan's window adaptation (step size, diagonal mass).

One transition of one chain is jitted once per Problem, with the step size and inverse mass
matrix as arguments; warmup (window-adaptation updates between transitions) and sampling
drive that same compiled step from a Python loop, chain by chain. So the physics is compiled
once per backend (not once for warmup and again per block of draws), and chains are not
vmapped (a vmapped NUTS builds every chain's tree in lock-step and compiles far slower).
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

from ..base import Backend, cached, register_backend, value_and_grad_fn

INITIAL_STEP_SIZE = 1.0


def chain_keys(key, n: int, chains: int) -> np.ndarray:
    """Keys for ``n`` transitions of ``chains`` chains: (n, chains, 2), a pure function of ``key``."""
    return np.asarray(jax.vmap(lambda k: jax.random.split(k, chains))(jax.random.split(key, n)))


def initial_states(problem, positions) -> HMCState:
    """HMC states at ``positions`` from the Problem's one compiled value-and-gradient."""
    vg = value_and_grad_fn(problem)
    pairs = [vg(x) for x in jnp.asarray(positions)]
    return HMCState(jnp.asarray(positions), jnp.stack([v for v, _ in pairs]),
                    jnp.stack([g for _, g in pairs]))


def unstack(tree, n: int) -> list:
    """A pytree with a leading chain axis as a list of ``n`` per-chain pytrees."""
    return [jax.tree_util.tree_map(lambda a: a[c], tree) for c in range(n)]


def stack(trees: list):
    """Inverse of ``unstack``."""
    return jax.tree_util.tree_map(lambda *a: jnp.stack(a), *trees)


class _BlackjaxHMCFamily(Backend):
    algorithm = None

    def _extra(self, settings) -> dict:
        return {}

    def _step(self, problem, settings):
        """jit(one transition of one chain): (key, state, step_size, imm) -> (state, info)."""
        extra = self._extra(settings)

        def build():
            def one(k, state, step_size, inverse_mass_matrix):
                return self.algorithm(problem.logdensity, step_size, inverse_mass_matrix,
                                      **extra).step(k, state)
            return jax.jit(one)

        return cached(problem, (self.name, "step", tuple(sorted(extra.items()))), build)

    def warmup(self, problem, positions, key, settings):
        with warnings.catch_warnings():  # base() is blackjax's documented building block
            warnings.simplefilter("ignore", DeprecationWarning)
            init, update, final = window_base(True, target_acceptance_rate=settings.target_accept)
        adapt = cached(problem, ("window-adaptation", settings.target_accept),
                       lambda: jax.jit(update))
        step = self._step(problem, settings)
        chains = positions.shape[0]
        states = unstack(initial_states(problem, positions), chains)
        astates = [init(s.position, INITIAL_STEP_SIZE) for s in states]
        n = settings.warmup
        schedule = np.asarray(build_schedule(n)) if n else np.zeros((0, 2), int)
        keys = chain_keys(key, n, chains) if n else []
        for i in range(n):
            stage = (jnp.asarray(schedule[i, 0], jnp.int32), jnp.asarray(schedule[i, 1], bool))
            for c in range(chains):
                states[c], info = step(keys[i][c], states[c], astates[c].step_size,
                                       astates[c].inverse_mass_matrix)
                astates[c] = adapt(astates[c], stage, states[c].position, info.acceptance_rate)
        step_size, inverse_mass_matrix = stack([final(a) for a in astates])
        params = {"step_size": step_size, "inverse_mass_matrix": inverse_mass_matrix}
        return stack(states), params, {"step_size": step_size}

    def sample(self, problem, states, params, key, n, settings):
        step = self._step(problem, settings)
        chains = np.shape(params["step_size"])[0]
        states = unstack(HMCState(*states), chains)
        per_chain = unstack(params, chains)
        draws, stats = [], []
        for k in chain_keys(key, n, chains):
            infos = []
            for c in range(chains):
                states[c], info = step(k[c], states[c], per_chain[c]["step_size"],
                                       per_chain[c]["inverse_mass_matrix"])
                infos.append(_stats(info))
            draws.append(np.stack([np.asarray(s.position) for s in states]))
            stats.append({name: np.stack([np.asarray(i[name]) for i in infos]) for name in infos[0]})
        return stack(states), np.stack(draws, axis=1), {k: np.stack([s[k] for s in stats], axis=1)
                                                        for k in stats[0]}


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

    def _extra(self, settings):
        return {"num_integration_steps": settings.integration_steps}
