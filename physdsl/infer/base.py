"""The one shape every inference backend takes, and the registry of backends by name.

A backend works on a log density over a flat unconstrained vector and the measurements
(``Problem.logdensity(x, data)``, numpyro's potential), blackjax-style: ``warmup`` tunes and returns per-chain states and
parameters; ``sample`` advances the chains by ``n`` draws. Both are pure functions of their
inputs (keys included), so running in blocks and resuming from a checkpoint gives the same
draws as one uninterrupted run. Compiled stages take ``problem.data`` as an argument and live
in ``problem.cache``, shared by every Model of one scene structure, so a new dataset reuses
them. A new backend is one module with ``@register_backend`` (in ``infer/backends/``, or a
plug-in's module named by an entry point of group ``physdsl.backends``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..ahead import Program, build_once
from ..errors import UsageError
from ..registry import Registry
from ..physics.forward import FORWARD_MODE_MAX, inline_calls, jacobian, prune

BACKENDS: Registry["Backend"] = Registry("physdsl.backends", "inference backend")


@dataclass(frozen=True)
class Settings:
    """What a user sets for a run; backends read the fields that concern them."""

    chains: int = 4
    warmup: int = 500
    samples: int | None = None  # draws per chain; None: the backend's ``default_samples``
    seed: int = 0
    target_accept: float = 0.8
    max_tree_depth: int = 8
    integration_steps: int = 16
    dense_mass: bool = True  # adapt a dense (not diagonal) mass matrix: unknowns of physical
    # scenes are few and strongly correlated (launch velocity against drag), and a dense
    # metric cuts the leapfrog steps per draw several-fold at negligible cost per step
    block: int = 100  # draws between checkpoints
    init_steps: int = 300  # optimisation steps from each prior draw before warmup; a chain
    # that ends far below the best (``map.major_modes``) starts from the best mode instead
    # constrained values ((name, value), ...) for the first chain's start, the other unknowns
    # and chains from the prior: a refit of a nested model starts where the smaller one ended
    start: tuple = ()
    intervals: str = "robust"  # what summary.csv shows: the widened draws (``robust``, see
    # ``intervals.py``) or the plain posterior (``model``); both are kept in posterior.nc


class Problem(NamedTuple):
    """A log density over flat unconstrained vectors and how to map draws back.

    ``logdensity`` and ``to_constrained`` are pure in ``(x, data)`` and shared by the Models of
    one scene structure; ``data`` is this Model's measurements (``Model.data``, as arrays).
    """

    logdensity: Callable[[jax.Array, Any], jax.Array]  # (flat, data) -> log p (finite or -inf)
    to_constrained: Callable[[jax.Array, Any], dict]  # (flat, data) -> {site: constrained value}
    dim: int
    model: Any  # the compiled Model (for backends that need the program itself)
    data: Any  # the measurements: the second argument of logdensity / to_constrained
    cache: dict  # compiled functions (taking data as an argument), shared by the structure
    # where the likelihood is least squares (else None): (flat, data) -> (log p, gradient,
    # J^T J: the likelihood's Gauss-Newton curvature), and flat -> the Hessian of -log prior
    gauss_newton: Callable[[jax.Array, Any], tuple] | None = None
    prior_hessian: Callable[[jax.Array], jax.Array] | None = None
    # where least squares: (flat, data) -> (sites, pointwise log-likelihood, log p) of one
    # draw through the scene's compiled rollout (``problem.draw_function``), else None
    draw: Callable[[jax.Array, Any], tuple] | None = None


class Backend:
    """Base class: a name, whether it needs gradients, and the two pure stages."""

    name: str = ""
    uses_gradient: bool = True
    default_samples: int = 500  # draws per chain where the user gives none

    def warmup(self, problem: Problem, positions: jax.Array, key, settings: Settings,
               on_block=None):
        """Tune on ``positions`` (chains, dim); return (states, params, info dict).
        ``on_block(m)``: called after each block of ``m`` warmup transitions (progress)."""
        raise NotImplementedError

    def sample(self, problem: Problem, states, params, key, n: int, settings: Settings,
               start: int = 0):
        """Advance chains by ``n``: the draws numbered ``start`` to ``start + n - 1`` of the run,
        whose random numbers come from ``key`` and their number alone (so any cut of the
        draws into calls gives the same draws); return (states, draws (chains, n, dim),
        stats {name: (chains, n)})."""
        raise NotImplementedError

    def gaussian(self, states, params):
        """(means (chains, dim), square roots (chains, dim, dim)) where every chain's draws are
        ``mean + sqrt @ z`` for standard normal z (``output.build_inference_data`` may then
        read their predictions off an expansion about each mean: ``local_pass``); None for
        Markov chains."""
        return None


def register_backend(cls):
    """Class decorator: make a backend available by its ``name``."""
    BACKENDS.add(cls.name, cls(), cls.__module__)
    return cls


def get_backend(name: str) -> Backend:
    """The backend registered as ``name`` (built-ins: ``infer/backends/``, registered when
    ``physdsl.infer`` is imported; plug-ins: entry-point group ``physdsl.backends``)."""
    if name not in BACKENDS:
        raise UsageError(f"unknown backend '{name}'",
                         hint=f"known backends: {', '.join(sorted(BACKENDS))}")
    return BACKENDS[name]


def cached(problem: Problem, key, build: Callable):
    """``problem.cache[key]``, built once: compiled stages are shared by runs on one Problem."""
    return build_once(problem.cache, key, build)


def value_and_grad_fn(problem: Problem):
    """x -> (log density, gradient) at ``problem``'s data; compiled once per scene structure
    (as part of ``gauss_newton_fn`` where that exists: one compile serves both)."""
    if problem.gauss_newton is not None:
        parts = _gauss_newton_parts(problem)
        return lambda x: parts(x)[:2]
    vg = cached(problem, "vg", lambda: Program(jax.value_and_grad(problem.logdensity)))
    data = problem.data
    return lambda x: vg(x, data)


def value_fn(problem: Problem):
    """x -> log density alone at ``problem``'s data (no tangents: a fraction of the cost of
    ``value_and_grad_fn`` on contact scenes); compiled once per scene structure. Where the
    Problem has ``draw`` (least squares), that: the posterior pass's function, whose rollout
    is the scene's one compiled rollout (shared with the predictions and the fit's quality)."""
    if problem.draw is not None:
        data = problem.data
        return lambda x: problem.draw(x, data)[2]
    f = cached(problem, "value", lambda: Program(problem.logdensity))
    data = problem.data
    return lambda x: f(x, data)


def gauss_newton_fn(problem: Problem):
    """x -> (log density, gradient, Gauss-Newton matrix J^T J + Hessian of -log prior: an
    approximation of the negative Hessian) at ``problem``'s data; None where the likelihood is
    not least squares. The likelihood's part is ``value_and_grad_fn``'s own compiled function
    (one compile serves both); the prior's, a small program with no rollout, is exact."""
    if problem.gauss_newton is None:
        return None
    parts = _gauss_newton_parts(problem)
    prior = cached(problem, "prior-hessian", lambda: Program(problem.prior_hessian))

    def gn(x):
        v, g, JJ = parts(x)
        return v, g, JJ + prior(x)

    return gn


def _gauss_newton_parts(problem: Problem):
    gn = problem.gauss_newton  # jitted (``ahead.Program``): compiled once per structure
    data = problem.data
    return lambda x: gn(x, data)


def gauss_newton(with_residuals):
    """(x, data) -> (log p, gradient, J^T J) with J = d residuals / dx; ``with_residuals``:
    (x, data) -> (log p, standardised residuals), from one rollout.

    For a likelihood -1/2 |r|^2 (plus noise-scale terms), J^T J is its curvature without
    second derivatives of the physics (Gauss-Newton). All from one forward-mode pass: the
    tangents that give the gradient pass through the residuals, so their Jacobian costs no
    extra rollout.
    """
    def fn(x, data):
        (v, r), (g, J) = _forward(with_residuals, x, data)
        H = J.reshape(x.size, -1) @ J.reshape(x.size, -1).T
        ok = jnp.isfinite(v) & jnp.all(jnp.isfinite(g)) & jnp.all(jnp.isfinite(H))
        return (jnp.where(ok, v, -jnp.inf), jnp.where(ok, g, 0.0), jnp.where(ok, H, 0.0))

    return fn


def bind(problem: Problem, data):
    """The log density of ``problem`` at ``data`` as a function of x alone (for use in traces)."""
    return lambda x: problem.logdensity(x, data)


def safe_logdensity(fn, value_and_grad=None):
    """Wrap a log density ``fn(x, data)`` so NaN/inf values or gradients become -inf with
    zero gradient (no gradient flows to ``data``).

    A rollout that blows up for some parameter values then is a rejected proposal, not a
    crash, and no NaN leaks into the sampler's state through the gradient. Without
    differentiation only the value is computed (gradient-free backends pay no gradient).
    ``value_and_grad``: a jitted (x, data) -> (value, gradient, ...) to take them from (the
    Gauss-Newton program, whose trace the mode search has made already), else forward mode.
    """

    # jitted, so a sampler that calls the log density at several places of its step (NUTS:
    # six, in its tree's loops) traces the rollout and its tangents once, not at each
    value = jax.jit(fn)
    if value_and_grad is None:
        value_and_grad = jax.jit(lambda x, data: _value_and_grad(fn, x, data))

    @jax.custom_vjp
    def f(x, data):
        v = value(x, data)
        return jnp.where(jnp.isfinite(v), v, -jnp.inf)

    def fwd(x, data):
        v, g = _clean(*value_and_grad(x, data)[:2])
        return v, (g, data)

    def bwd(res, ct):
        g, data = res
        return ct * g, jax.tree_util.tree_map(_zero_cotangent, data)

    f.defvjp(fwd, bwd)
    return f


def _value_and_grad(fn, x, data):
    """``fn(x, data)`` and its gradient in ``x``: by forward mode (one tangent per dimension) for
    at most ``FORWARD_MODE_MAX`` dimensions, else by reverse mode.

    The rollout's derivatives are forward-mode anyway (``simulator.forward_mode``); carrying the
    few tangents on through the interpolation and the likelihood leaves no reverse pass at all,
    which traces and compiles to fewer, fused kernels (no scatter-adds, no transposed products)
    and runs no slower for the handful of unknowns of a physical scene. The tangents are read
    off ``fn``'s jaxpr (``forward.jacobian``): numpyro's handlers, distributions and whatever
    does not depend on ``x`` are then traced once, plainly, not under a vmapped jvp.
    """
    if x.size > FORWARD_MODE_MAX:
        return jax.value_and_grad(fn)(x, data)
    (v,), (g,) = _forward(lambda x, data: (fn(x, data),), x, data)
    return v, g


def _forward(fn, x, data):
    """(outputs of ``fn(x, data)`` (a tuple), their derivatives in ``x``, (dim, *shape) each) by
    forward mode read off ``fn``'s jaxpr, as ``_value_and_grad`` explains."""
    leaves, tree = jax.tree_util.tree_flatten((x, data))
    closed = jax.make_jaxpr(lambda *xs: fn(*jax.tree_util.tree_unflatten(tree, xs)))(*leaves)
    # the rollout inline (``rollouts=True``): its loops take these tangents
    values, tangents = jacobian(prune(inline_calls(closed, rollouts=True))[0], leaves, [0])
    return values, [jnp.zeros((x.size,) + jnp.shape(v), v.dtype) if t is None else t
                    for v, t in zip(values, tangents)]


def _zero_cotangent(a):
    if jnp.issubdtype(a.dtype, jnp.inexact):
        return jnp.zeros_like(a)
    return np.zeros(a.shape, dtype=jax.dtypes.float0)


def _clean(v, g):
    """(v, g), or (-inf, zeros) if any of them is not finite: one check and one select over
    the value and gradient side by side (separate ones compile to a kernel each)."""
    vg = jnp.concatenate([v[None], g])
    ok = jnp.all(jnp.isfinite(vg))
    out = jnp.where(ok, vg, jnp.where(jnp.arange(vg.size) == 0, -jnp.inf, 0.0))
    return out[0], out[1:]
