"""A control (or design) problem: which unknowns are chosen, where the others are held, and the
goal's cost as a function of the chosen ones in the prior's unconstrained space.

Choosing in the prior's unconstrained space (numpyro's bijections) keeps every choice inside
its prior's support: a control written ``values ~ uniform(-10 N, 10 N)`` is bounded by
construction. The other unknowns sit at the prior's centre, or at posterior draws, over which
the cost is averaged (a plan robust to what the fit left uncertain).
"""
from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer.util import constrain_fn, unconstrain_fn

from ..compile import Model
from ..errors import ModelError
from ..goal import Goal
from ..infer.multistart import prior_centre
from ..infer.posterior_data import group, posterior_draws
from ..infer.problem import model_problem, unconstrained_layout, unraveler
from .cost import check_goal, control_effects, goal_residuals, term_errors


@dataclass(frozen=True)
class ControlProblem:
    """The chosen unknowns' places in the flat unconstrained vector and the rows that hold the
    others (one row: the prior's centre; several: posterior draws)."""

    model: Model
    goal: Goal
    chosen: tuple[str, ...]
    index: np.ndarray  # (k,) positions of the chosen unknowns in the flat vector
    rows: np.ndarray  # (S, dim) unconstrained rows for everything else

    @property
    def start(self) -> np.ndarray:
        """The chosen unknowns' start: the first row's (the prior centre's) coordinates."""
        return self.rows[0, self.index]


def chosen_unknowns(model: Model, goal: Goal) -> tuple[str, ...]:
    """The scene's unknown control sequences, then the goal's other decisions."""
    names = set(model.unknown_names)
    for name in goal.decisions:
        if name not in names:
            raise ModelError(f"goal: '{name}' is not an unknown of the scene", span=goal.span,
                             hint="a decision must be written with `~` (its prior bounds it); "
                                  f"unknowns: {', '.join(model.unknown_names) or 'none'}")
    controls = [n for n in control_effects(model.scene) if n in names]
    chosen = tuple(dict.fromkeys(controls + list(goal.decisions)))
    if not chosen:
        raise ModelError("nothing to choose: the scene has no unknown control sequence and the "
                         "goal names no decision", span=goal.span,
                         hint="write a control with `values ~ uniform(...)`, or name an unknown "
                              "in the goal's `decide:`")
    return chosen


def flat_slices(model: Model) -> dict[str, slice]:
    """Where each unknown sits in the flat unconstrained vector (``ravel_pytree``'s order)."""
    layout = unconstrained_layout(model)
    out, at = {}, 0
    for name in sorted(layout):
        size = int(np.prod(layout[name].shape))
        out[name] = slice(at, at + size)
        at += size
    return out


def build(model: Model, goal: Goal, idata=None, draws: int = 16, seed: int = 0) -> ControlProblem:
    """The ControlProblem of ``goal`` on ``model``; with ``idata``, the unchosen unknowns at up
    to ``draws`` posterior draws, else at the prior's centre."""
    check_goal(model.scene, model.simulator, goal)
    chosen = chosen_unknowns(model, goal)
    slices = flat_slices(model)
    index = np.concatenate([np.arange(slices[n].start, slices[n].stop) for n in chosen])
    centre = prior_centre(model_problem(model), jax.random.PRNGKey(seed))
    rows = centre[None, :]
    if idata is not None:
        rows = _posterior_rows(model, idata, draws, centre, slices)
    return ControlProblem(model, goal, chosen, index, np.asarray(rows, dtype=float))


def _posterior_rows(model: Model, idata, draws: int, centre, slices) -> np.ndarray:
    """Posterior draws of the fitted unknowns as unconstrained rows (the prior centre elsewhere)."""
    held = set(group(idata, "posterior").data_vars)
    fitted = [n for n in model.unknown_names if n in held]
    if not fitted:
        raise ModelError("the posterior holds none of the scene's unknowns",
                         hint="give the run folder of a fit of this scene (`physdsl infer`)")
    values = posterior_draws(idata, fitted, max_draws=draws)
    n = len(next(iter(values.values())))
    base = constrain(model, jnp.asarray(centre))
    rows = []
    for i in range(n):
        v = {k: jnp.asarray(a) for k, a in base.items()}
        v.update({k: jnp.asarray(values[k][i]) for k in fitted})
        free = unconstrain_fn(model.prior_values, (), {}, v)
        row = np.array(centre, dtype=float)
        for k in fitted:
            row[slices[k]] = np.ravel(free[k])
        rows.append(row)
    return np.stack(rows)


def constrain(model: Model, x):
    """The unknowns' values (name -> array, SI) at the flat unconstrained vector ``x``."""
    unravel, _ = unraveler(unconstrained_layout(model))
    return constrain_fn(model.prior_values, (), {}, unravel(x))


def full_vector(problem: ControlProblem, z, row):
    """The flat unconstrained vector: ``row`` with the chosen coordinates replaced by ``z``."""
    return jnp.asarray(row).at[problem.index].set(z)


def residual_fn(problem: ControlProblem):
    """z -> the goal's residuals at every row, scaled so their squared sum is the mean cost
    over the rows (pure, jit- and grad-able)."""
    model, goal, rows = problem.model, problem.goal, jnp.asarray(problem.rows)
    scale = 1.0 / np.sqrt(rows.shape[0])

    def one(z, row):
        values = constrain(model, full_vector(problem, z, row))
        rollout = model.simulator.simulate(values)
        return goal_residuals(model.scene, model.simulator, goal, rollout, values, problem.chosen)

    return lambda z: scale * jnp.ravel(jax.vmap(one, in_axes=(None, 0))(z, rows))


def cost_fn(problem: ControlProblem):
    """z -> the mean goal cost over the problem's rows (the residuals' squared sum)."""
    residuals = residual_fn(problem)
    return lambda z: jnp.sum(residuals(z) ** 2)


def outcome(problem: ControlProblem, z) -> tuple[dict, object, list]:
    """(values, rollout, term errors) at the chosen ``z`` with the first row's other unknowns."""
    model = problem.model
    values = constrain(model, full_vector(problem, jnp.asarray(z), problem.rows[0]))
    rollout = model.simulator.simulate(values)
    return values, rollout, term_errors(model.scene, model.simulator, problem.goal, rollout, values,
                                        problem.chosen)
