"""Inverse rendering of one image: which primitive, where, how big, what colour, what light.

The unknown object is a categorical shape (sphere, cylinder, box) and a continuous vector:
position (3, m), orientation as a rotation vector (3, rad), log half-extents (3, shared by the
shapes: see ``shape_size``), colour logits (3), log material ambient and
diffuse factors (2), and the light direction's tilt from its nominal value (2, rad). The
prior is independent Normal in these coordinates (``ShapePrior``) and uniform over shapes.

Sampling is Metropolis-within-Gibbs: a step for the continuous block given the shape, then a
Metropolis move of the shape to another kind drawn uniformly, keeping the continuous values.
The continuous step is a blackjax ``normal_random_walk`` (``continuous="rw"``: per-chain scale
adapted towards 25 % acceptance during warmup) or an HMC step (``continuous="hmc"``: the
renderer's gradients; step size adapted towards 75 % acceptance, a diagonal mass matrix from
the first half of warmup).
Each chain starts from a jittered prior mean improved by a short Adam fit of the continuous
block for every shape, at the best-fitting shape (a multi-start: the random walk starts in
the typical set instead of spending its budget finding the object). The
likelihood is ``image_log_likelihood`` (blur pyramid) of the rendered image. ``render_grid``
draws posterior samples beside the target (the PhysWM figure of posterior draws).
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import blackjax
import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..observe.image import image_log_likelihood
from .render import render
from .types import BOX, CYLINDER, KIND_NAMES, SPHERE, RenderCamera, Light, Objects, make_objects

SHAPES = (SPHERE, CYLINDER, BOX)  # categorical index -> kind code
DIM = 16
_POS, _ROT, _SIZE, _COLOR, _MAT, _LIGHT = (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12),
                                           slice(12, 14), slice(14, 16))


class Context(NamedTuple):
    """What is known about the image: camera, background, the nominal light, and fixed
    objects (e.g. the ground plane) drawn with the unknown one."""

    camera: RenderCamera
    light: Light
    background: jax.Array  # (3,)
    fixed: Objects | None = None


class ShapePrior(NamedTuple):
    """Independent Normal prior of the continuous block: ``mean`` and ``sd`` (DIM,)."""

    mean: jax.Array
    sd: jax.Array


def default_prior(center, center_sd=0.1, size=0.05, size_sd=0.7) -> ShapePrior:
    """Position near ``center`` (m), half-sizes around ``size`` (m, log-normal), any colour,
    material factors near 1, light direction within ~0.2 rad of nominal."""
    mean = np.zeros(DIM)
    sd = np.ones(DIM)
    mean[_POS], sd[_POS] = np.asarray(center, dtype=float), center_sd
    sd[_ROT] = 1.5
    mean[_SIZE], sd[_SIZE] = np.log(size), size_sd
    sd[_COLOR] = 2.0
    sd[_MAT] = 0.3
    sd[_LIGHT] = 0.2
    return ShapePrior(jnp.asarray(mean), jnp.asarray(sd))


# a random-walk step per coordinate before adaptation (m, rad, log, logit, log, rad)
_STEP = np.concatenate([np.full(3, 2e-3), np.full(3, 0.05), np.full(3, 0.02), np.full(3, 0.05),
                        np.full(2, 0.02), np.full(2, 0.02)])


def _rotvec_quat(v):
    angle = jnp.sqrt(jnp.sum(v * v) + 1e-24)
    return jnp.concatenate([jnp.cos(0.5 * angle)[None], jnp.sin(0.5 * angle) * v / angle])


def _tilt(direction, angles):
    """The unit ``direction`` turned by two small angles about two axes perpendicular to it."""
    d = direction / jnp.linalg.norm(direction)
    ref = jnp.where(jnp.abs(d[0]) < 0.9, jnp.array([1.0, 0, 0]), jnp.array([0.0, 1, 0]))
    e1 = jnp.cross(d, ref)
    e1 = e1 / jnp.linalg.norm(e1)
    e2 = jnp.cross(d, e1)
    out = d + angles[0] * e1 + angles[1] * e2
    return out / jnp.linalg.norm(out)


def shape_size(log_half, kind):
    """Renderer size of ``kind`` from shared log half-extents (a, b, c) along x, y, z: box
    (a, b, c), cylinder (radius sqrt(ab), half-length c), sphere radius (abc)^(1/3). Shared so
    that a shape move keeps the object's extent and the move can be accepted."""
    la = log_half
    sphere = jnp.stack([jnp.exp(jnp.mean(la)), 0.0, 0.0])
    cylinder = jnp.stack([jnp.exp(0.5 * (la[0] + la[1])), jnp.exp(la[2]), 0.0])
    return jnp.where(kind == SPHERE, sphere, jnp.where(kind == CYLINDER, cylinder, jnp.exp(la)))


def decode(theta, shape):
    """(Objects with the one unknown object, light direction tilt angles) from ``theta``."""
    kind = jnp.asarray(SHAPES)[shape]
    size = shape_size(theta[_SIZE], kind)
    mat = jnp.exp(theta[_MAT])
    obj = Objects(kind=kind[None], pos=theta[None, _POS], quat=_rotvec_quat(theta[_ROT])[None],
                  size=size[None], color=jax.nn.sigmoid(theta[_COLOR])[None],
                  ambient=mat[:1], diffuse=mat[1:], visible=jnp.ones(1))
    return obj, theta[_LIGHT]


def render_theta(theta, shape, context: Context, softness=0.5):
    """The image of the unknown object at ``theta``/``shape`` with the context's fixed objects."""
    obj, tilt = decode(theta, shape)
    if context.fixed is not None:
        obj = Objects(*(jnp.concatenate([a, b]) for a, b in zip(context.fixed, obj)))
    light = context.light._replace(direction=_tilt(context.light.direction, tilt))
    return render(obj, light, context.camera, context.background, softness)


def log_posterior(theta, shape, target, context: Context, prior: ShapePrior, sigma=0.05,
                  levels: int = 3):
    """Log prior + image log-likelihood (uniform prior over shapes)."""
    image = render_theta(theta, shape, context)
    lp = -0.5 * jnp.sum(((theta - prior.mean) / prior.sd) ** 2)
    return lp + image_log_likelihood(image, target, sigma, levels=levels, kind="student_t")


class Draws(NamedTuple):
    """Posterior draws: ``theta`` (chains, n, DIM), ``shape`` (chains, n) categorical index
    into SHAPES, and each chain's continuous-block acceptance rate."""

    theta: np.ndarray
    shape: np.ndarray
    accept: np.ndarray

    @property
    def kind_names(self) -> np.ndarray:
        return np.vectorize(lambda s: KIND_NAMES[SHAPES[s]])(self.shape)

    def objects(self, chain: int, i: int) -> Objects:
        return decode(jnp.asarray(self.theta[chain, i]), int(self.shape[chain, i]))[0]


def sample(target, context: Context, prior: ShapePrior, key, chains: int = 3, warmup: int = 400,
           samples: int = 400, sigma: float = 0.05, init_steps: int = 150, levels: int = 3,
           continuous: str = "rw", leapfrog: int = 8) -> Draws:
    """Posterior draws of the unknown object behind ``target`` (H, W, 3 in [0, 1]).

    ``continuous``: "rw" (random walk) or "hmc" (``leapfrog`` steps per move) for the
    continuous block; the shape always moves by Metropolis.
    """
    if continuous not in ("rw", "hmc"):
        raise ValueError(f"continuous must be 'rw' or 'hmc', not {continuous!r}")
    target = jnp.asarray(target)

    def logdensity(theta, shape):
        return log_posterior(theta, shape, target, context, prior, sigma, levels)

    theta0, shape0 = _initial(logdensity, prior, jax.random.fold_in(key, 0), chains, init_steps)
    scale0 = jnp.asarray(_STEP)
    move = _rw_move if continuous == "rw" else partial(_hmc_move, leapfrog=leapfrog)
    goal = 0.25 if continuous == "rw" else 0.75

    def gibbs(carry, key, adapt, scale):
        theta, shape, logp, log_step, t = carry
        k1, k2, k3 = jax.random.split(key, 3)
        theta, logp, accept = move(k1, lambda x: logdensity(x, shape), theta, logp,
                                   jnp.exp(log_step), scale)
        if adapt:
            log_step = log_step + (accept - goal) * 2.0 / (t + 10.0) ** 0.6
        # shape move: another kind uniformly, continuous values kept (symmetric proposal)
        new = (shape + jax.random.randint(k2, (), 1, len(SHAPES))) % len(SHAPES)
        logp_new = logdensity(theta, new)
        take = jnp.log(jax.random.uniform(k3)) < logp_new - logp
        shape = jnp.where(take, new, shape)
        logp = jnp.where(take, logp_new, logp)
        return (theta, shape, logp, log_step, t + 1), (theta, shape, accept)

    def run_chain(theta, shape, key):
        kw, ks = jax.random.split(key)
        carry = (theta, shape, logdensity(theta, shape), jnp.zeros(()), jnp.zeros(()))
        scale, n_warm = scale0, warmup
        if continuous == "hmc" and warmup >= 16:  # first half of warmup: a diagonal metric
            kh, kw = jax.random.split(kw)
            half = warmup // 2
            carry, (th, _, _) = jax.lax.scan(lambda c, k: gibbs(c, k, True, scale0), carry,
                                             jax.random.split(kh, half))
            scale = jnp.sqrt(0.8 * jnp.var(th[half // 2:], axis=0) + 0.2 * scale0 ** 2)
            # the same move length in the new metric; the adaptation restarts
            carry = carry[:3] + (carry[3] + jnp.mean(jnp.log(scale0 / scale)), jnp.zeros(()))
            n_warm = warmup - half
        carry, _ = jax.lax.scan(lambda c, k: gibbs(c, k, True, scale), carry,
                                jax.random.split(kw, n_warm))
        _, (th, sh, acc) = jax.lax.scan(lambda c, k: gibbs(c, k, False, scale), carry,
                                        jax.random.split(ks, samples))
        return th, sh, acc.mean()

    keys = jax.random.split(jax.random.fold_in(key, 1), chains)
    th, sh, acc = jax.jit(jax.vmap(run_chain))(theta0, shape0, keys)
    return Draws(np.asarray(th), np.asarray(sh), np.asarray(acc))


def _rw_move(key, logdensity, theta, logp, step, scale):
    """One random-walk Metropolis step with per-coordinate scale ``step * scale``."""
    rw = blackjax.normal_random_walk(logdensity, step * scale)
    state, info = rw.step(key, blackjax.mcmc.random_walk.RWState(theta, logp))
    return state.position, state.logdensity, info.is_accepted.astype(float)


def _hmc_move(key, logdensity, theta, logp, step, scale, leapfrog: int):
    """One HMC step (``leapfrog`` steps of size ``step``, inverse mass ``scale**2``); the
    returned rate is the move's acceptance probability (smoother for adaptation)."""
    del logp  # the state is rebuilt with the gradient at this shape
    state = blackjax.mcmc.hmc.init(theta, logdensity)
    state, info = _HMC_KERNEL(key, state, logdensity, step, scale ** 2, leapfrog)
    return state.position, state.logdensity, info.acceptance_rate


_HMC_KERNEL = blackjax.mcmc.hmc.build_kernel()


def _initial(logdensity, prior: ShapePrior, key, chains: int, steps: int):
    """Each chain's start (theta, shape): a jittered prior mean fitted by ``steps`` Adam steps
    for every shape; the chain starts at the shape whose fit has the highest log posterior."""
    theta = prior.mean + 0.1 * prior.sd * jax.random.normal(key, (chains, DIM))
    if steps <= 0:
        return theta, jnp.arange(chains) % len(SHAPES)
    opt = optax.adam(optax.exponential_decay(0.02, steps, 0.1))

    def fit(theta, shape):
        loss = jax.value_and_grad(lambda x: -logdensity(x, shape))

        def step(carry, _):
            x, st, best, best_x = carry
            v, g = loss(x)
            g = jnp.where(jnp.isfinite(g), g, 0.0)
            upd, st = opt.update(g, st)
            better = v < best
            return (optax.apply_updates(x, upd), st, jnp.where(better, v, best),
                    jnp.where(better, x, best_x)), None

        (_, _, best, best_x), _ = jax.lax.scan(step, (theta, opt.init(theta), jnp.inf, theta),
                                               None, length=steps)
        return best_x, best

    def per_chain(theta):
        xs, losses = jax.vmap(fit, in_axes=(None, 0))(theta, jnp.arange(len(SHAPES)))
        best = jnp.argmin(losses)
        return xs[best], best

    return jax.jit(jax.vmap(per_chain))(theta)


def render_grid(draws: Draws, target, context: Context, n: int = 8, seed: int = 0,
                pad: int = 2) -> np.ndarray:
    """One image (H', W', 3): the target on the left, then ``n`` posterior draws rendered with
    the context, in a row, separated by ``pad`` white pixels."""
    rng = np.random.default_rng(seed)
    chains, m = draws.shape.shape
    picks = [(rng.integers(chains), rng.integers(m)) for _ in range(n)]
    images = [np.asarray(render_theta(jnp.asarray(draws.theta[c, i]), int(draws.shape[c, i]),
                                      context)) for c, i in picks]
    return grid([np.asarray(target)] + images, pad)


def grid(images, pad: int = 2, columns: int | None = None) -> np.ndarray:
    """Images (H, W, 3) tiled in rows of ``columns`` (default: one row) with white padding."""
    columns = columns or len(images)
    h, w = images[0].shape[:2]
    rows = -(-len(images) // columns)
    out = np.ones((rows * (h + pad) + pad, columns * (w + pad) + pad, 3))
    for i, img in enumerate(images):
        r, c = divmod(i, columns)
        out[pad + r * (h + pad):pad + r * (h + pad) + h,
            pad + c * (w + pad):pad + c * (w + pad) + w] = img
    return out


__all__ = ["SHAPES", "Context", "Draws", "ShapePrior", "decode", "default_prior", "grid",
           "log_posterior", "make_objects", "render_grid", "render_theta", "sample"]
