"""Effect registry and the Load an effect returns: world forces/torques per body plus joint forces.

An effect is a pure function ``force(model, site, p, ctx) -> Load`` registered under its
name in ``EFFECTS`` (entry-point group ``physdsl.effects``), with what it acts on; ``p`` holds
the use's evaluated parameters, ``ctx`` the kinematics and time. Its parameters, units, priors
and off values are the language's: ``stdlib/effects/<name>.phys`` for physdsl's own (whose
``on ...`` a test checks against ``acts_on``), the ``declaration`` block given to
``register`` for a plug-in's (the ``effect_type NAME on ...`` line is written from the
registration, so a plug-in states its name and targets once).
Effects with ``stage="contact"`` (friction, restitution) are read by the contact stage instead.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import jax.numpy as jnp

from ...errors import ModelError
from ...registry import EFFECT_DECLARATIONS, Registry
from ..kinematics import Kin
from ..rows import spread, take


class Ctx(NamedTuple):
    """What an effect may read: kinematics, params, time, gravity, last contact normal forces."""

    kin: Kin
    prm: dict
    t: jnp.ndarray  # time of this evaluation (RK4 stage time)
    t_step: jnp.ndarray  # start of the current (sub)step: controls are held over a step
    gravity: jnp.ndarray  # (3,) total gravitational acceleration (for buoyancy)
    contact_force: jnp.ndarray  # (C,) normal forces of the previous step
    contact_normal: jnp.ndarray  # (C, 3)


class Load(NamedTuple):
    """Applied loads: world force at each body's COM, world torque per body, joint forces."""

    force: jnp.ndarray  # (B, 3)
    torque: jnp.ndarray  # (B, 3)
    joint: jnp.ndarray  # (nv,)

    def __add__(self, other):  # type: ignore[override]
        return Load(self.force + other.force, self.torque + other.torque, self.joint + other.joint)


def zero_load(model, dtype=float) -> Load:
    """No load at all."""
    B = model.nbody
    return Load(jnp.zeros((B, 3), dtype), jnp.zeros((B, 3), dtype), jnp.zeros(model.nv, dtype))


@dataclass(frozen=True)
class Effect:
    name: str
    force: Callable | None
    acts_on: tuple[str, ...]  # subset of body, world, joint, pair
    stage: str = "force"
    validate: Callable | None = None  # extra static check (scene, use, joint) -> None
    # the force acts at the centre of mass, with no torque, and depends only on the COM's
    # position and velocity (``kin.com``, ``kin.vcom``), params, time and gravity: free bodies
    # under central effects alone translate and rotate independently (physics/central.py)
    central: bool = False

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


EFFECTS: Registry[Effect] = Registry("physdsl.effects", "effect")


def register(name: str, acts_on: tuple[str, ...], stage: str = "force", validate=None,
             central: bool = False, declaration: str | None = None):
    """Decorator registering ``force`` as the physics of effect ``name``. ``declaration``: the
    ``{ doc ... param ... }`` block of an effect with no file in ``stdlib/`` (a plug-in's)."""
    def deco(fn):
        EFFECTS.add(name, Effect(name, fn, acts_on, stage, validate, central), fn.__module__)
        if declaration is not None:
            EFFECT_DECLARATIONS.add(name, declaration_text(name, acts_on, declaration),
                                    fn.__module__)
        return fn
    return deco


def declaration_text(name: str, acts_on: tuple[str, ...], block: str) -> str:
    """The .phys ``effect_type`` of a registered effect from its ``{ ... }`` block."""
    return f"effect_type {name} on {' or '.join(acts_on)} {block.strip()}\n"


def wrenches(model, ctx: Ctx, bodies, forces, points=None, torques=None) -> Load:
    """Load of world forces (n, 3) on ``bodies`` at world points (default: COMs), plus torques."""
    dtype = ctx.kin.com.dtype
    forces = jnp.broadcast_to(jnp.asarray(forces, dtype), (len(bodies), 3))
    T = None
    if points is not None:
        T = jnp.cross(points - take(ctx.kin.com, bodies), forces)
    if torques is not None:
        T = torques if T is None else T + torques
    F = spread(model.nbody, bodies, forces)
    T = jnp.zeros_like(F) if T is None else spread(model.nbody, bodies, jnp.broadcast_to(T, forces.shape))
    return Load(F, T, jnp.zeros(model.nv, dtype))


def wrench(model, ctx: Ctx, body: int, force, point=None, torque=None) -> Load:
    """Load of one world force on ``body`` at a world point (default: its COM), plus a torque."""
    pts = None if point is None else point[None]
    return wrenches(model, ctx, (body,), force[None], pts, None if torque is None else torque[None])


def com_velocity(ctx: Ctx, bodies):
    """World velocities (n, 3) of the bodies' centres of mass."""
    return take(ctx.kin.vcom, bodies)


def joint_forces(model, site, gen) -> Load:
    """Load of a joint's generalized force (its dofs)."""
    tau = jnp.zeros(model.nv, dtype=gen.dtype)
    if site.dofs:  # a joint's dofs are contiguous
        tau = tau.at[site.dofs[0]:site.dofs[-1] + 1].set(gen)
    z = jnp.zeros((model.nbody, 3), gen.dtype)
    return Load(z, z, tau)


def joint_velocity(ctx: Ctx, site):
    return take(ctx.kin.v, site.dofs) if site.dofs else jnp.zeros(0)


def moving(model, bodies) -> tuple[int, ...]:
    """The bodies that have a dof somewhere on their path to world."""
    return tuple(b for b in bodies if model.ancestors_dofs(b))
