"""Choose the unknowns that meet a goal: prior draws screened in one batched rollout, then
L-BFGS (optax, zoom line search) from the best few, through the differentiable rollout.

A goal reached through a contact has flat regions (a push that misses the other ball moves
nothing), where a gradient method started in the wrong place never leaves; screening draws of
the prior first is the cheap global step, the gradient the precise local one. The chosen
coordinates are scaled by the prior's spread, so one step length suits every unknown.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..infer.problem import model_problem, prior_draws_unconstrained
from .cost import met
from .problem import ControlProblem, cost_fn, outcome

SCREENED = 32  # prior draws whose cost is evaluated in one batch
REFINED = 2  # best screened starts (the prior centre among the candidates) refined by L-BFGS
RELATIVE_TOL = 1e-10  # stop when the cost falls by less than this fraction over PATIENCE steps
PATIENCE = 5
MET_EXACTLY = 1e-12  # or when it is this small: every error a millionth of its tolerance


@dataclass
class Plan:
    """The choice that meets (or best approaches) a goal, and how it was reached."""

    values: dict[str, np.ndarray]  # every unknown, SI (the chosen ones and those held)
    chosen: tuple[str, ...]
    cost: float
    errors: list[float]  # per goal term, in its unit (m, rad; effort in N² s)
    met: bool
    history: list[float] = field(default_factory=list)  # cost per step of the winning start
    rollout: object = None
    screened: int = 0


def candidate_starts(problem: ControlProblem, n: int = SCREENED, seed: int = 0):
    """(starts (n + 1, k): the prior centre's choice then n prior draws', their spread (k,))."""
    draws = prior_draws_unconstrained(model_problem(problem.model), jax.random.PRNGKey(seed), n)
    chosen = np.asarray(draws)[:, problem.index]
    spread = np.std(chosen, axis=0)
    spread = np.where(spread > 0, spread, 1.0)
    return np.vstack([problem.start[None, :], chosen]), spread


def optimise(problem: ControlProblem, steps: int = 200, on_step=None, screened: int = SCREENED,
             refined: int = REFINED, seed: int = 0) -> Plan:
    """Screen ``screened`` prior draws, refine the best ``refined`` with L-BFGS, keep the best.
    ``on_step(start, i, cost)`` reports progress."""
    cost = cost_fn(problem)
    starts, spread = candidate_starts(problem, screened, seed)
    batch = np.asarray(jax.jit(jax.vmap(cost))(jnp.asarray(starts)))
    order = np.argsort(np.where(np.isfinite(batch), batch, np.inf))[:max(refined, 1)]
    centre = jnp.asarray(problem.start)
    scaled = lambda w: cost(centre + jnp.asarray(spread) * w)  # noqa: E731
    step = _lbfgs_step(scaled)
    best = None
    for s, i in enumerate(order):
        w, history = _descend(step, (starts[i] - problem.start) / spread, steps,
                              None if on_step is None else (lambda k, c, s=s: on_step(s, k, c)))
        if best is None or history[-1] < best[1][-1]:
            best = (w, history)
    z = centre + jnp.asarray(spread) * jnp.asarray(best[0])
    final = float(cost(z))
    values, rollout, errors = outcome(problem, z)
    errors = [float(e) for e in errors]
    return Plan({k: np.asarray(v) for k, v in values.items()}, problem.chosen, final, errors,
                met(problem.goal, errors), best[1] + [final], rollout, len(starts))


def _lbfgs_step(cost):
    solver = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(cost)

    @jax.jit
    def step(w, state):
        value, grad = value_and_grad(w, state=state)
        updates, state = solver.update(grad, state, w, value=value, grad=grad, value_fn=cost)
        return optax.apply_updates(w, updates), state, value

    return solver, step


def _descend(solver_step, w0, steps: int, on_step) -> tuple[np.ndarray, list[float]]:
    """L-BFGS from ``w0`` until the cost stops falling; the last finite point and its history."""
    solver, step = solver_step
    w = jnp.asarray(w0)
    state = solver.init(w)
    history: list[float] = []
    for k in range(steps):
        w_next, state_next, value = step(w, state)
        value = float(value)
        if not np.isfinite(value):
            break
        history.append(value)
        if on_step is not None:
            on_step(k, value)
        if not np.all(np.isfinite(np.asarray(w_next))):
            break
        w, state = w_next, state_next
        if value <= MET_EXACTLY or len(history) > PATIENCE and (
                history[-PATIENCE - 1] - value <= RELATIVE_TOL * max(abs(value), 1e-300)):
            break
    return np.asarray(w), history or [float("inf")]
