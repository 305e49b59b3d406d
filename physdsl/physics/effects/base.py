"""Effect registry and helpers mapping world wrenches to generalized forces (J^T f).

An effect is a pure function ``force(model, site, p, ctx) -> tau (nv,)`` registered under its
stdlib name; ``p`` holds the use's evaluated parameters, ``ctx`` the kinematics and time.
Effects with ``stage="contact"`` (friction, restitution) are read by the contact stage instead.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import jax.numpy as jnp

from ...errors import ModelError
from ..kinematics import Kin
from ..spatial import point_wrench


class Ctx(NamedTuple):
    """What an effect may read: kinematics, params, time, gravity, last contact normal forces."""

    kin: Kin
    prm: dict
    t: jnp.ndarray  # time of this evaluation (RK4 stage time)
    t_step: jnp.ndarray  # start of the current (sub)step: controls are held over a step
    gravity: jnp.ndarray  # (3,) total gravitational acceleration (for buoyancy)
    contact_force: jnp.ndarray  # (C,) normal forces of the previous step
    contact_normal: jnp.ndarray  # (C, 3)


@dataclass(frozen=True)
class Effect:
    name: str
    force: Callable | None
    acts_on: tuple[str, ...]  # subset of body, world, joint, pair
    stage: str = "force"
    validate: Callable | None = None  # extra static check (scene, use, joint) -> None

    def check(self, scene, use, bodies, joint) -> None:
        """Reject targets this effect cannot act on (static, at build time)."""
        if use.target == ("world",):
            kind = "world"
        elif joint is not None:
            kind = "joint"
        elif len(bodies) == 2:
            kind = "pair"
        else:
            kind = "body"
        ok = kind in self.acts_on or (kind == "world" and "body" in self.acts_on)
        if not ok:
            raise ModelError(f"effect '{self.name}' cannot act on a {kind} ('{','.join(use.target)}')",
                             span=use.span, hint=f"it acts on: {', '.join(self.acts_on)}")
        if self.validate is not None:
            self.validate(scene, use, joint)


EFFECTS: dict[str, Effect] = {}


def register(name: str, acts_on: tuple[str, ...], stage: str = "force", validate=None):
    """Decorator registering ``force`` as the physics of stdlib effect ``name``."""
    def deco(fn):
        EFFECTS[name] = Effect(name, fn, acts_on, stage, validate)
        return fn
    return deco


def wrenches(ctx: Ctx, bodies, forces, points=None, torques=None):
    """Generalized forces of world forces (n, 3) on ``bodies`` at world points (default: COMs)."""
    idx = jnp.asarray(bodies)
    kin = ctx.kin
    pts = kin.com[idx] if points is None else points
    n = jnp.cross(pts, forces)
    if torques is not None:
        n = n + torques
    f = jnp.concatenate([n, forces], -1)
    return jnp.einsum("bkn,bk->n", kin.jac[idx], f)


def wrench(ctx: Ctx, body: int, force, point=None, torque=None):
    """Generalized force of one world force on ``body`` at a world point (default: its COM)."""
    pt = ctx.kin.com[body] if point is None else point
    return ctx.kin.jac[body].T @ point_wrench(force, pt, torque)


def com_velocity(ctx: Ctx, bodies):
    """World velocities (n, 3) of the bodies' centres of mass."""
    idx = jnp.asarray(bodies)
    vel = ctx.kin.vel[idx]
    return vel[:, 3:] + jnp.cross(vel[:, :3], ctx.kin.com[idx])


def joint_forces(model, site, gen):
    """Scatter a joint's generalized force (its dofs) into a full (nv,) vector."""
    tau = jnp.zeros(model.nv, dtype=gen.dtype)
    if not site.dofs:
        return tau
    return tau.at[jnp.asarray(site.dofs)].set(gen)


def joint_velocity(ctx: Ctx, site):
    return ctx.kin.v[jnp.asarray(site.dofs)] if site.dofs else jnp.zeros(0)


def moving(model, bodies) -> tuple[int, ...]:
    """The bodies that have a dof somewhere on their path to world."""
    return tuple(b for b in bodies if model.ancestors_dofs(b))
