"""A contact that never comes near costs (next to) nothing: free flight first, contacts if needed.

Free bodies moved by central effects alone (``central.decoupled``) fly on the cheap split path
(translation alone when the caller reads positions). With contact pairs, the rollout first
flies them so, as if there were no pairs, and checks along that flight whether any candidate
pair comes within reach: the gap between bounding spheres about the bodies' centres (a plane:
its half-space) must stay above the contact margin plus twice the distance the pair can close
over one recorded interval. Where it does, no step of the contact rollout would meet a contact
(``integrate.step`` takes the integrator's own step there), so the flight is the rollout (equal
to 1e-12); elsewhere the contact rollout runs. The choice is a ``lax.cond``, or, in rollouts
differentiated in forward mode, a while loop of at most one trip (``integrate.either``), so
vmapped chains skip the contact rollout when none of them comes near.
"""
from __future__ import annotations

import dataclasses

import jax.numpy as jnp

from . import central
from .contact import contact_margin
from .integrate import either
from .model import build_model
from .structure import PhysicsModel

PRIMITIVES = ("sphere", "box", "capsule", "cylinder", "plane")


def free_scene(scene, model: PhysicsModel):
    """``scene`` without its contact pairs and its PhysicsModel, where that flies on the split path;
    else None."""
    if not model.ncon or any(k not in PRIMITIVES for p in model.pairs for k in (p.kind_a, p.kind_b)):
        return None
    free = dataclasses.replace(scene, contact_pairs=())
    free_model = build_model(free)
    return (free, free_model) if central.decoupled(free_model) else None


def bounding_radius(kind: str, size):
    """Bounding-sphere radius about the body origin (the centre of a primitive)."""
    if kind == "sphere":
        return size[0]
    if kind == "box":
        return jnp.linalg.norm(size)
    if kind == "capsule":
        return size[0] + size[1]
    return jnp.hypot(size[0], size[1])  # cylinder


def clear(model: PhysicsModel, prm: dict, pos, vel, pairs=None):
    """True if no contact pair (of ``pairs``, indices into ``model.pairs``; default all) comes
    within reach along the flight ``pos``/``vel`` (T, B, 3)."""
    return clearance(model, prm, pos, vel, pairs) > 0.0


def clearance(model: PhysicsModel, prm: dict, pos, vel, pairs=None):
    """How far (m) the pairs (of ``pairs``; default all) stay beyond their reach along the
    flight ``pos``/``vel`` (T, B, 3), at the closest: ``clear`` where positive (inf: no pair)."""
    span = model.dt * model.substeps  # between recorded states
    speed = jnp.linalg.norm(vel, axis=-1)  # (T, B)
    speed = jnp.maximum(speed[1:], speed[:-1])  # over each interval
    least = jnp.asarray(jnp.inf, pos.dtype)
    for p in model.pairs if pairs is None else [model.pairs[k] for k in pairs]:
        a, b, ka, kb = p.a, p.b, p.kind_a, p.kind_b
        if ka == "plane":
            a, b, ka, kb = b, a, kb, ka
        ra = bounding_radius(ka, prm["size"][a])
        if kb == "plane":
            n = prm["size"][b] / jnp.linalg.norm(prm["size"][b])
            gap = (pos[:, a] - pos[:, b]) @ n - ra
        else:
            gap = (jnp.linalg.norm(pos[:, a] - pos[:, b], axis=-1) - ra
                   - bounding_radius(kb, prm["size"][b]))
        gap = jnp.minimum(gap[1:], gap[:-1])
        least = jnp.minimum(least, jnp.min(
            gap - contact_margin - 2.0 * span * (speed[:, a] + speed[:, b])))
    return least


def free_unless_near(model: PhysicsModel, prm: dict, free, contact, values, forward_only: bool):
    """The flight ``free`` (a Rollout) where ``clear``, else ``contact(values)`` (a Rollout, cut
    to the fields that ``free`` has), by ``integrate.either``."""
    C = model.ncon

    def fly(_):
        return free._replace(contact_force=jnp.zeros(free.t.shape + (C,), free.t.dtype))

    def touch(values):
        out = contact(values)
        return out._replace(**{f: None for f in out._fields if getattr(free, f) is None})

    near = ~clear(model, prm, free.body_pos, free.body_vel)
    return either(near, touch, fly, values, forward_only)
