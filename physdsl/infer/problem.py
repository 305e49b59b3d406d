"""From a compiled Model to a Problem: numpyro's potential in unconstrained space, flattened.

The unconstrained space is that of the prior program alone (the physics adds only
deterministic and observed sites), so building it never runs or compiles the rollout. The
log density takes the measurements as an argument (``Problem.data``), and its functions
and every compiled stage (``Problem.cache``) are shared by all Models of one scene
structure: another dataset or another ``until`` cut-off reuses them without recompiling.
"""
from __future__ import annotations

import weakref

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
from jax.flatten_util import ravel_pytree
from numpyro.infer.util import constrain_fn, potential_energy, unconstrain_fn

from ..ahead import Program
from ..compile import PRED_PREFIX
from ..errors import InferenceError
from ..physics.forward import FORWARD_MODE_MAX
from .base import Problem, cached, gauss_newton, safe_logdensity, value_and_grad_fn
from .left_out import CLEARANCE_SITE
from .threads import split, thread_map, workers

_PROBLEMS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
INIT_ROUNDS = 10  # rounds of prior draws tried before giving up on a finite start


def model_problem(model) -> Problem:
    """The Problem of ``model`` (made once per Model and cached)."""
    if model not in _PROBLEMS:
        _PROBLEMS[model] = _build_problem(model)
    return _PROBLEMS[model]


def _build_problem(model) -> Problem:
    discrete = [u.name for u in model.unknowns if u.discrete]
    if discrete:
        raise InferenceError(f"discrete unknowns ({', '.join(discrete)}) are not supported by "
                             "trajectory inference yet",
                             hint="give them a value, or fit shape from images with "
                                  "physdsl.render.inverse (Metropolis-within-Gibbs)")
    logdensity, to_constrained, dim, gn, ph, draw = model.cached("problem",
                                                                 lambda: _functions(model))
    data = jax.device_put(model.data)  # (jnp.asarray would compile a conversion per array)
    return Problem(logdensity, to_constrained, dim, model, data, model.compiled.cache, gn, ph,
                   draw)


def _functions(model):
    """(log density (x, data), to_constrained (x, data), dim) of ``model``'s structure."""
    unravel, dim = unraveler(unconstrained_layout(model))

    def logdensity(x, data):
        return -potential_energy(model.numpyro_model, (data,), {}, unravel(x))

    def to_constrained(x, data):
        return constrain_fn(model.numpyro_model, (data,), {}, unravel(x), return_deterministic=True)

    with_residuals, neg_log_prior = least_squares_parts(model, unravel)
    if not (model.least_squares and dim <= FORWARD_MODE_MAX):
        return safe_logdensity(logdensity), to_constrained, dim, None, None, None
    # one trace serves the fit and the samplers
    gn = model.cached("gauss-newton", lambda: Program(gauss_newton(with_residuals)))
    return (safe_logdensity(logdensity, gn), to_constrained, dim, gn,
            jax.hessian(neg_log_prior), draw_function(model, unravel, neg_log_prior))


def draw_function(model, unravel, neg_log_prior):
    """(x, data) -> (sites: the unknowns' constrained values and the ``pred:`` predictions;
    pointwise log-likelihood by observable; log density) of one flat unconstrained draw.

    Three compiled parts: constraining (no physics), the scene's rollout itself
    (``model.fit_simulate``: the likelihood's Simulator's one compiled rollout, which the fit's
    quality and ``check`` call too) and the predictions and likelihood read off it (no
    physics; with the check of the contact pairs the likelihood leaves out). The log
    density is the Gauss-Newton function's (``least_squares_parts``; -inf where not finite),
    so the fit's value function is this one (``base.value_fn``) and the posterior pass
    (``output.posterior_pass``) reuses its compiled rollout instead of tracing another."""
    def read_off(x, values, rollout, data):
        preds = model.predict(values, rollout, data)
        ll = model.pointwise_log_likelihood(values, preds, data)
        lp = sum((jnp.sum(v) for v in ll.values()), -neg_log_prior(x))
        sites = {**values, **{PRED_PREFIX + k: v for k, v in preds.items()}}
        if model.ruled_out:  # the check of a likelihood without some pairs (``left_out``)
            sites[CLEARANCE_SITE] = model.left_out_clearance(values, rollout)
        return sites, ll, jnp.where(jnp.isfinite(lp), lp, -jnp.inf)

    # in the structure's cache by name, like every compiled stage (shared by other data)
    constrain = model.cached("draw-constrain", lambda: Program(
        lambda x: constrain_fn(model.prior_values, (), {}, unravel(x))))
    read = model.cached("draw-read", lambda: Program(read_off))

    def draw(x, data):
        values = constrain(x)
        return read(x, values, model.fit_simulate(values), data)

    draw.constrain = constrain  # x -> the unknowns' constrained values (``local_pass``)
    return draw


def drawn(problem, xs) -> list:
    """(sites, pointwise log-likelihood) of each flat draw of ``xs`` through ``problem.draw``,
    from ``threads.workers()`` threads: each thread dispatches its calls, then waits once,
    so the calls overlap."""
    data = problem.data
    return [o for part in thread_map(lambda part: jax.device_get(
        [problem.draw(jnp.asarray(x), data)[:2] for x in part]), split(xs, workers()))
        for o in part]


def least_squares_parts(model, unravel):
    """(with_residuals (x, data) -> (log density, standardised residuals) from one rollout,
    neg_log_prior (x)) in the flat unconstrained space ``unravel`` reads: what a Gauss-Newton
    matrix is made of (``base.gauss_newton``; also used beyond ``FORWARD_MODE_MAX`` unknowns by
    ``discover.learn``, which trains a network's weights so)."""
    def neg_log_prior(x):
        return potential_energy(model.prior_values, (), {}, unravel(x))

    def with_residuals(x, data):  # the log density and the standardised residuals, one rollout
        values = constrain_fn(model.prior_values, (), {}, unravel(x))
        preds = model.predict(values, data=data)
        ll = model.pointwise_log_likelihood(values, preds, data)
        return (sum((jnp.sum(v) for v in ll.values()), -neg_log_prior(x)),
                model.standardized_residuals(values, preds, data))

    return with_residuals, neg_log_prior


def unconstrained_layout(model) -> dict:
    """Shapes of the unconstrained sites (name -> ShapeDtypeStruct), in the flat vector's
    order (``ravel_pytree``'s: the names sorted)."""
    def unconstrained_draw(key):
        with numpyro.handlers.seed(rng_seed=key):
            draw = model.prior_values()
        return unconstrain_fn(model.prior_values, (), {}, draw)

    # only the layout is needed: shapes by abstract evaluation (running the prior eagerly, or
    # even making a key, would compile each of its operations on its own)
    return jax.eval_shape(unconstrained_draw, jax.ShapeDtypeStruct((2,), jnp.uint32))


def unraveler(layout):
    """(unravel, size) for pytrees shaped as ``layout`` (of ShapeDtypeStructs): the inverse of
    ``ravel_pytree`` (same leaf order), made without running anything."""
    leaves, tree = jax.tree_util.tree_flatten(layout)
    sizes = [int(np.prod(leaf.shape)) for leaf in leaves]
    cuts = np.cumsum(sizes)[:-1].tolist()

    def unravel(x):
        parts = jnp.split(x, cuts) if cuts else [x]
        return jax.tree_util.tree_unflatten(
            tree, [p.reshape(leaf.shape).astype(leaf.dtype) for p, leaf in zip(parts, leaves)])

    return unravel, sum(sizes)


def prior_draws_unconstrained(problem: Problem, key, n: int) -> np.ndarray:
    """``n`` prior draws as flat unconstrained vectors (n, dim); runs no physics."""
    return np.asarray(_prior_draws_program(problem, n)(jax.random.split(key, n)))


def prior_draws_ahead(problem: Problem, n: int) -> None:
    """Start compiling ``prior_draws_unconstrained``'s program for ``n`` draws (``ahead``)."""
    keys = jax.eval_shape(lambda: jax.random.split(jax.random.PRNGKey(0), n))
    _prior_draws_program(problem, n).ahead(keys)


def _prior_draws_program(problem: Problem, n: int) -> Program:
    """keys (n, ...) -> (n, dim) prior draws, flat and unconstrained (one program per n)."""
    model = problem.model

    def one(k):
        with numpyro.handlers.seed(rng_seed=k):
            values = model.prior_values()
        return ravel_pytree(unconstrain_fn(model.prior_values, (), {}, values))[0]

    return cached(problem, ("prior-draws", n), lambda: Program(jax.vmap(one)))


def start_position(problem: Problem, key, start: dict) -> np.ndarray:
    """A flat unconstrained vector holding the constrained values ``start`` (name -> value) and
    a prior draw for every other unknown."""
    model = problem.model
    with numpyro.handlers.seed(rng_seed=key):
        values = model.prior_values()
    values.update({k: jnp.broadcast_to(jnp.asarray(v, dtype=jnp.result_type(float)),
                                       jnp.shape(values[k]))
                   for k, v in start.items() if k in values})
    return np.asarray(ravel_pytree(unconstrain_fn(model.prior_values, (), {}, values))[0])


def initial_positions(problem: Problem, key, chains: int, start: dict | None = None) -> jnp.ndarray:
    """One prior draw per chain at which the log density and its gradient are finite; with
    ``start`` (constrained values by name) the first chain starts there instead, if finite.

    Draws are tried in order, in rounds of ``max(4 * chains, 8)``; each is checked with the
    Problem's one compiled value-and-gradient function.
    """
    vg = value_and_grad_fn(problem)
    found: list[np.ndarray] = []
    if start:
        x = start_position(problem, key, start)
        v, g = vg(jnp.asarray(x))
        if np.isfinite(float(v)) and np.all(np.isfinite(np.asarray(g))):
            found.append(x)
            if len(found) == chains:
                return jnp.asarray(np.stack(found))
    n = max(4 * chains, 8)
    for r in range(INIT_ROUNDS):
        for x in prior_draws_unconstrained(problem, jax.random.fold_in(key, r), n):
            v, g = vg(jnp.asarray(x))
            if np.isfinite(float(v)) and np.all(np.isfinite(np.asarray(g))):
                found.append(x)
                if len(found) == chains:
                    return jnp.asarray(np.stack(found))
    raise InferenceError("no prior draw gives a finite likelihood",
                         hint=f"tried {INIT_ROUNDS * n} draws; check priors and units: the "
                              "rollout may blow up for every draw")


def make_problem(model, key, chains: int, start: dict | None = None):
    """Return (Problem, initial flat positions (chains, dim)) drawn from the prior (the first
    at ``start`` where given, see ``initial_positions``)."""
    problem = model_problem(model)
    return problem, initial_positions(problem, key, chains, start)
