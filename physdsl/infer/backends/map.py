"""MAP by L-BFGS in unconstrained space, with a Laplace approximation for uncertainty.

The optimiser (scipy's L-BFGS-B) drives one jitted value-and-gradient function of the log
density, so the physics is compiled once however many iterations, line searches and chains
run. The Hessian at the mode comes from central differences of that same gradient (no second
compile). 'Draws' are independent samples of the Gaussian centred at each chain's mode with
the inverse Hessian as covariance, in unconstrained space, so constrained draws respect supports.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize

from ..base import Backend, register_backend, value_and_grad_fn  # noqa: F401 - re-exported


def find_mode(problem, x0, steps: int = 300) -> np.ndarray:
    """Maximise the log density from ``x0`` with L-BFGS; returns the best point found."""
    vg = value_and_grad_fn(problem)

    def neg(x):
        v, g = vg(jnp.asarray(x))
        v, g = float(v), np.asarray(g, dtype=float)
        if not np.isfinite(v):
            return 1e300, np.zeros_like(g)
        return -v, -g

    x0 = np.asarray(x0, dtype=float)
    res = minimize(neg, x0, jac=True, method="L-BFGS-B", options={"maxiter": steps})
    return res.x if np.isfinite(res.fun) and res.fun <= neg(x0)[0] else x0


def find_modes(problem, positions, steps: int = 300) -> jnp.ndarray:
    """``find_mode`` from each row of ``positions``."""
    return jnp.asarray(np.stack([find_mode(problem, x, steps) for x in np.asarray(positions)]))


def laplace_cov(problem, mode) -> np.ndarray:
    """Inverse of the negative Hessian at ``mode`` by central differences of the gradient."""
    vg = value_and_grad_fn(problem)
    mode = np.asarray(mode, dtype=float)
    d = mode.size
    h = 1e-5 * np.maximum(1.0, np.abs(mode))
    H = np.zeros((d, d))
    for i in range(d):
        e = np.zeros(d)
        e[i] = h[i]
        gp = np.asarray(vg(jnp.asarray(mode + e))[1])
        gm = np.asarray(vg(jnp.asarray(mode - e))[1])
        H[:, i] = -(gp - gm) / (2 * h[i])
    H = 0.5 * (H + H.T)
    w, v = np.linalg.eigh(H)
    w = np.where(np.isfinite(w) & (w > 1e-10), w, 1e-10)
    return (v / w) @ v.T


@register_backend
class MAP(Backend):
    name = "map"

    def warmup(self, problem, positions, key, settings):
        steps = max(settings.warmup, 50)
        modes = find_modes(problem, positions, steps)
        chols = np.stack([np.linalg.cholesky(laplace_cov(problem, m) + 1e-12 * np.eye(problem.dim))
                          for m in np.asarray(modes)])
        vg = value_and_grad_fn(problem)
        lps = np.array([float(vg(m)[0]) for m in modes])
        return modes, {"chol": jnp.asarray(chols)}, {"log_density_at_mode": lps}

    def sample(self, problem, states, params, key, n, settings):
        keys = jax.random.split(key, states.shape[0])
        z = jax.vmap(lambda k: jax.random.normal(k, (n, states.shape[1])))(keys)
        draws = states[:, None, :] + jnp.einsum("cij,cnj->cni", params["chol"], z)
        return states, draws, {}
