"""constant_force: a constant world force at the centre of mass, plus a constant world torque.

The strength ``force`` does not switch the torque off: ``torque`` defaults to 0, and a user
who sets it gets that torque even with ``force: 0``.
"""
import jax.numpy as jnp

from .base import register, wrenches


@register("constant_force", ("body",))
def constant_force(model, site, p, ctx):
    n = len(site.bodies)
    F = jnp.broadcast_to(p["force"], (n, 3))
    T = jnp.broadcast_to(p.get("torque", jnp.zeros(3)), (n, 3))
    return wrenches(model, ctx, site.bodies, F, torques=T)
