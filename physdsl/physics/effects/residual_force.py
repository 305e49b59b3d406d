"""residual_force / residual_joint_force: a small learned force, outside the library.

F = scale * MLP(features) / sqrt(hidden): a one-hidden-layer tanh network (equinox) from
physically meaningful features of the target's state to a generalized force. On a body the
features are its COM velocity v / speed, |v| / speed, its position relative to ``center``
d = (x - center) / length and |d|; on a hinge or slider the joint coordinate q / span and rate
qdot / rate. The weights are one vector unknown (``weights``, sized by ``hidden`` at resolve
time: ``syntax/learned.py``) with a normal prior, so MAP is training with weight decay; all
weights 0 gives exactly zero force (the off value), and the prior keeps the force near
``scale``. Equinox because its modules are pytrees: the flat weight vector numpyro samples
unravels into a network inside the traced rollout, with no init/apply state to thread.
"""
from __future__ import annotations

from functools import lru_cache

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from ...errors import ModelError
from ..rows import take
from .base import com_velocity, joint_forces, joint_velocity, register, wrenches

# (features in, generalized force out) per effect; syntax/learned.py sizes the weights alike
SIZES = {"residual_force": (8, 3), "residual_joint_force": (2, 1)}


def weights_size(n_in: int, hidden: int, n_out: int) -> int:
    """Number of weights of the network: two dense layers with biases."""
    return n_in * hidden + hidden + hidden * n_out + n_out


@lru_cache(maxsize=16)
def _template(n_in: int, hidden: int, n_out: int):
    """(unravel, static part) of an MLP of this shape: the weights vector becomes a network."""
    with jax.ensure_compile_time_eval():
        mlp = eqx.nn.MLP(n_in, n_out, hidden, depth=1, activation=jnp.tanh,
                         key=jax.random.PRNGKey(0))
        params, static = eqx.partition(mlp, eqx.is_array)
        flat, unravel = ravel_pytree(params)
    assert flat.size == weights_size(n_in, hidden, n_out)
    return unravel, static


def hidden_of(n_weights: int, n_in: int, n_out: int) -> int:
    """The hidden width a weights vector of this size belongs to."""
    hidden, rest = divmod(n_weights - n_out, n_in + 1 + n_out)
    if rest or hidden < 1:
        raise ModelError(f"{n_weights} weights fit no network with {n_in} inputs and "
                         f"{n_out} outputs")
    return hidden


def network(weights, features, n_out: int):
    """MLP(features) / sqrt(hidden) for the flat ``weights`` (0 where all weights are 0)."""
    n_in = features.shape[-1]
    hidden = hidden_of(int(weights.size), n_in, n_out)
    unravel, static = _template(n_in, hidden, n_out)
    mlp = eqx.combine(unravel(weights.astype(features.dtype)), static)
    return mlp(features) / jnp.sqrt(float(hidden))


def smooth_norm(x, eps=1e-9):
    """|x| with a finite derivative at 0."""
    return jnp.sqrt(jnp.sum(x * x, axis=-1, keepdims=True) + eps * eps)


def body_features(v, x, p):
    """(8,) features of a body state: v/speed, |v|/speed, d = (x - center)/length, |d|."""
    u = v / p["speed"]
    d = (x - p["center"]) / p["length"]
    return jnp.concatenate([u, smooth_norm(u), d, smooth_norm(d)])


def joint_features(q, qd, p):
    """(2,) features of a joint state: q/span, qdot/rate."""
    return jnp.concatenate([q / p["span"], qd / p["rate"]])


@register("residual_force", ("body",), central=True)
def residual_force(model, site, p, ctx):
    v = com_velocity(ctx, site.bodies)[0]
    x = take(ctx.kin.com, site.bodies)[0]
    f = p["scale"] * network(p["weights"], body_features(v, x, p), 3)
    return wrenches(model, ctx, site.bodies, f[None])


def _check_joint(scene, use, joint):
    kind = scene.joints[joint].kind if joint is not None else None
    if kind not in (None, "hinge", "slider"):
        raise ModelError(f"residual_joint_force acts on hinges and sliders, not on the {kind} "
                         f"joint '{scene.joints[joint].name}'", span=use.span)


@register("residual_joint_force", ("joint",), validate=_check_joint)
def residual_joint_force(model, site, p, ctx):
    tree = next(j for j in model.joints if j.scene_joint == site.joint)
    q = ctx.kin.q[tree.qadr: tree.qadr + tree.nq]
    qd = joint_velocity(ctx, site)
    return joint_forces(model, site, p["scale"] * network(p["weights"], joint_features(q, qd, p), 1))
