"""Refit a controller's physical unknowns online: MAP with a Laplace covariance, each refit
from the transitions seen since the last one, the last refit's Laplace approximation as their
prior (the model's prior at the first): a bounded memory that forgets nothing it learnt.

Each transition (x, u, x') scores the model's prediction ``f(params(z), x, u)`` against x'
with Gaussian noise (``PROCESS_NOISE``: coordinates, velocities), in the prior's unconstrained
space (every estimate stays in its prior's support). Levenberg-Marquardt on these few unknowns
converges in a handful of steps, warm-started at the last estimate; the new transitions sit in
fixed arrays (masked), so one compile serves the run.
"""
from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .transition import Transition

PROCESS_NOISE = (1e-4, 1e-3)  # per period: coordinates (m, rad), velocities (m/s, rad/s)
ITERATIONS = 12  # Levenberg-Marquardt steps per refit
CAPACITY = 100  # transitions held between refits (the latest)


@dataclass
class Memory:
    """The latest transitions in fixed arrays: x (N, nx), u (N, nu), x' (N, nx), mask (N,)."""

    x: np.ndarray
    u: np.ndarray
    x_next: np.ndarray
    mask: np.ndarray
    count: int = 0

    @classmethod
    def empty(cls, nx: int, nu: int, capacity: int = CAPACITY) -> "Memory":
        return cls(np.zeros((capacity, nx)), np.zeros((capacity, nu)), np.zeros((capacity, nx)),
                   np.zeros(capacity))

    def clear(self) -> None:
        self.mask[:] = 0.0
        self.count = 0

    def add(self, x, u, x_next) -> None:
        i = self.count % len(self.mask)
        self.x[i], self.u[i], self.x_next[i], self.mask[i] = x, u, x_next, 1.0
        self.count += 1


def map_fit(transition: Transition, noise=PROCESS_NOISE, iterations: int = ITERATIONS):
    """A jitted (z0, x, u, x', mask, centre, precision, first) -> (z, precision of z) for
    ``transition``'s unknowns: the prior is the model's where ``first`` is 1, else the Gaussian
    of ``centre`` and ``precision`` (the last refit's Laplace approximation)."""
    half = len(transition.joints)
    scale = jnp.concatenate([jnp.full(half, noise[0]), jnp.full(half, noise[1])])

    def residuals(z, x, u, x_next, mask):
        pred = jax.vmap(transition.step, in_axes=(None, 0, 0))(transition.params(z), x, u)
        return jnp.ravel((pred - x_next) / scale * jnp.sqrt(mask)[:, None])

    def expand(z, data):
        """(loss, gradient, Gauss-Newton Hessian with the prior's exact Hessian) at ``z``:
        one forward-mode pass through the physics gives the residuals and their Jacobian."""
        x, u, x_next, mask, centre, precision, first = data
        J, r = jax.jacfwd(lambda z: _twice(residuals(z, x, u, x_next, mask)), has_aux=True)(z)

        def prior(z):
            d = z - centre
            return first * transition.neg_log_prior(z) + (1.0 - first) * 0.5 * d @ precision @ d

        H = J.T @ J + jax.hessian(prior)(z)
        return 0.5 * r @ r + prior(z), J.T @ r + jax.grad(prior)(z), 0.5 * (H + H.T)

    def iteration(_, carry):
        z, (value, g, H), damping, data = carry
        trial = z - jnp.linalg.solve(H + damping * jnp.diag(jnp.abs(jnp.diag(H)) + 1e-9), g)
        new = expand(trial, data)
        better = jnp.isfinite(new[0]) & (new[0] < value)
        keep = jax.tree_util.tree_map(lambda a, b: jnp.where(better, a, b), (trial, new),
                                      (z, (value, g, H)))
        return keep + (jnp.where(better, damping / 3.0, damping * 4.0), data)

    @jax.jit
    def fit(z0, x, u, x_next, mask, centre, precision, first):
        data = (x, u, x_next, mask, centre, precision, first)
        z, (_, _, H), _, _ = jax.lax.fori_loop(0, iterations, iteration,
                                               (z0, expand(z0, data), 1e-3, data))
        return z, H

    return fit


def _twice(r):
    return r, r


def constrained_sd(transition: Transition, z, cov) -> dict[str, float]:
    """The estimates' standard deviations in SI (delta method through the prior's transform)."""
    def flat(z):
        values = transition.values(z)
        return jnp.concatenate([jnp.ravel(values[n]) for n in transition.physical])

    J = jax.jacfwd(flat)(jnp.asarray(z))
    var = np.diag(np.asarray(J @ cov @ J.T))
    return {n: float(np.sqrt(max(v, 0.0))) for n, v in zip(transition.physical, var)}
