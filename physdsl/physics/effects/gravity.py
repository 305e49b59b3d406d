"""gravity: F = m g at every body's centre of mass (world effect)."""
import jax.numpy as jnp

from .base import moving, register, wrenches


@register("gravity", ("world", "body"))
def gravity(model, site, p, ctx):
    bodies = moving(model, site.bodies)
    if not bodies:
        return jnp.zeros(model.nv)
    m = ctx.prm["mass"][jnp.asarray(bodies)]
    return wrenches(ctx, bodies, m[:, None] * p["acceleration"][None, :])
