"""distilled_law: the physics of a law distilled from a learned force (outside the library).

Registered here, with no declaration in ``stdlib/``: each distilled law comes with its own
``effect_type distilled_law on body|joint { param TERM: UNIT ... off 0 }``, listing only the
terms it keeps (``terms.py``), so the scene that uses it says exactly which law it is. On a
body F = sum_k c_k phi_k(v, x - center); on a hinge or slider tau = sum_k c_k phi_k(q, qdot).
"""
from __future__ import annotations

import jax.numpy as jnp

from ..physics.effects.base import com_velocity, joint_forces, joint_velocity, register, wrenches
from ..physics.rows import take
from .terms import TERMS, body_law, joint_law

NAME = "distilled_law"


@register(NAME, ("body", "joint"))
def distilled_law(model, site, p, ctx):
    coefficients = {k: v for k, v in p.items() if k in TERMS}
    if site.joint is None:
        v = com_velocity(ctx, site.bodies)
        d = take(ctx.kin.com, site.bodies) - p.get("center", jnp.zeros(3))
        return wrenches(model, ctx, site.bodies, body_law(coefficients, v, d))
    tree = next(j for j in model.joints if j.scene_joint == site.joint)
    q = ctx.kin.q[tree.qadr: tree.qadr + tree.nq]
    return joint_forces(model, site, joint_law(coefficients, q, joint_velocity(ctx, site)))
