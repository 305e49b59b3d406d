"""Choose the unknowns that meet a goal: prior draws screened in one batched rollout, then
Levenberg-Marquardt from the best few, through the differentiable rollout.

A goal reached through a contact has flat regions (a push that misses the other ball moves
nothing), where a gradient method started in the wrong place never leaves; screening draws of
the prior first is the cheap global step, the local one is the fits' Levenberg-Marquardt
(``infer.backends.map``) on the goal's residuals: every goal term is a squared error, so the
Gauss-Newton matrix from the rollout's forward-mode Jacobian knows the cost's curvature and
its scales (tens of steps where L-BFGS, rebuilding curvature from steps, took hundreds).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from ..infer import levenberg_marquardt
from ..infer.base import gauss_newton
from ..infer.problem import model_problem, prior_draws_unconstrained
from .cost import met
from .problem import ControlProblem, cost_fn, outcome, residual_fn

SCREENED = 32  # prior draws whose cost is evaluated in one batch
REFINED = 2  # best screened starts (the prior centre among the candidates) refined


@dataclass
class Plan:
    """The choice that meets (or best approaches) a goal, and how it was reached."""

    values: dict[str, np.ndarray]  # every unknown, SI (the chosen ones and those held)
    chosen: tuple[str, ...]
    cost: float
    errors: list[float]  # per goal term, in its unit (m, rad; effort in N² s)
    met: bool
    history: list[float] = field(default_factory=list)  # best cost after each evaluation
    rollout: object = None
    screened: int = 0


def candidate_starts(problem: ControlProblem, n: int = SCREENED, seed: int = 0):
    """The prior centre's choice then ``n`` prior draws' (n + 1, k)."""
    draws = prior_draws_unconstrained(model_problem(problem.model), jax.random.PRNGKey(seed), n)
    return np.vstack([problem.start[None, :], np.asarray(draws)[:, problem.index]])


def optimise(problem: ControlProblem, steps: int = 200, on_step=None, screened: int = SCREENED,
             refined: int = REFINED, seed: int = 0) -> Plan:
    """Screen ``screened`` prior draws, refine the best ``refined`` by Levenberg-Marquardt, keep
    the best. ``on_step(start, evaluation, best cost)`` reports progress."""
    cost = jax.jit(cost_fn(problem))
    starts = candidate_starts(problem, screened, seed)
    batch = np.asarray(jax.jit(jax.vmap(cost_fn(problem)))(jnp.asarray(starts)))
    order = np.argsort(np.where(np.isfinite(batch), batch, np.inf))[:max(refined, 1)]
    residuals = residual_fn(problem)

    def with_residuals(x, _):  # one rollout gives the log density and the residuals
        r = residuals(x)
        return -0.5 * jnp.sum(r ** 2), r

    curvature = jax.jit(lambda z: gauss_newton(with_residuals)(z, None))
    value = lambda z: -0.5 * cost(z)  # noqa: E731 - the compiled cost, no second program
    best = None
    for s, i in enumerate(order):
        history: list[float] = []
        z = levenberg_marquardt.run(_recorded(curvature, history, s, on_step), starts[i], steps,
                                    value)
        reached = float(cost(z))
        if best is None or reached < best[1]:
            best = (z, reached, history)
    z, final, history = best
    values, rollout, errors = outcome(problem, z)
    errors = [float(e) for e in errors]
    return Plan({k: np.asarray(v) for k, v in values.items()}, problem.chosen, final, errors,
                met(problem.goal, errors), history + [final], rollout, len(starts))


def _recorded(curvature, history: list[float], start: int, on_step):
    """``curvature`` that appends the best cost so far to ``history`` at each evaluation."""
    def fn(z):
        v, g, H = curvature(z)
        cost = -2.0 * float(v)
        history.append(min([cost] + history[-1:]) if np.isfinite(cost) else
                       (history[-1] if history else float("inf")))
        if on_step is not None:
            on_step(start, len(history) - 1, history[-1])
        return v, g, H
    return fn
