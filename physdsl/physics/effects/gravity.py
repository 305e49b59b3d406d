"""gravity: F = m g at every body's centre of mass (world effect)."""
import jax.numpy as jnp

from ..rows import take
from .base import register, wrenches


@register("gravity", ("world",), central=True)
def gravity(model, site, p, ctx):
    m = take(ctx.prm["mass"], site.bodies)  # static bodies ignore their load
    return wrenches(model, ctx, site.bodies, m[:, None] * p["acceleration"][None, :])
