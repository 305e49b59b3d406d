"""MAP by optax (Adam then L-BFGS) in unconstrained space, with a Laplace approximation.

The 'draws' are independent samples of the Gaussian centred at each chain's mode with the
inverse Hessian of the negative log density as covariance (in unconstrained space, so the
constrained draws respect supports). Fast, and the right first step for a refit.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import optax

from ..base import Backend, register_backend


def find_mode(logdensity, x0, steps: int = 300):
    """Maximise ``logdensity`` from ``x0`` with optax L-BFGS (line search); returns the mode."""
    loss = lambda x: -logdensity(x)  # noqa: E731
    opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(loss)

    def body(carry, _):
        x, state = carry
        value, grad = value_and_grad(x, state=state)
        updates, state = opt.update(grad, state, x, value=value, grad=grad, value_fn=loss)
        x_new = optax.apply_updates(x, updates)
        x_new = jnp.where(jnp.all(jnp.isfinite(x_new)), x_new, x)
        return (x_new, state), value

    (x, _), _ = jax.lax.scan(body, (x0, opt.init(x0)), None, length=steps)
    return x


def laplace_cov(logdensity, mode):
    """Covariance of the Laplace approximation at ``mode`` (regularised if not positive)."""
    h = -jax.hessian(logdensity)(mode)
    h = 0.5 * (h + h.T)
    w, v = jnp.linalg.eigh(h)
    w = jnp.where(jnp.isfinite(w) & (w > 1e-10), w, 1e-10)
    return (v / w) @ v.T


@register_backend
class MAP(Backend):
    name = "map"

    def warmup(self, problem, positions, key, settings):
        steps = max(settings.warmup, 50)

        def one(x):
            mode = find_mode(problem.logdensity, x, steps)
            cov = laplace_cov(problem.logdensity, mode)
            return mode, jnp.linalg.cholesky(cov + 1e-12 * jnp.eye(cov.shape[0]))

        modes, chols = jax.jit(jax.vmap(one))(positions)
        lps = jax.vmap(problem.logdensity)(modes)
        return modes, {"chol": chols}, {"log_density_at_mode": lps}

    def sample(self, problem, states, params, key, n, settings):
        def chain(k, mode, p):
            z = jax.random.normal(k, (n, mode.shape[0]))
            return mode + z @ p["chol"].T

        keys = jax.random.split(key, states.shape[0])
        draws = jax.jit(jax.vmap(chain))(keys, states, params)
        stats = {"log_density": jax.vmap(jax.vmap(problem.logdensity))(draws)}
        return states, draws, stats
