"""buoyancy: F = -rho V g at the centre of volume (= COM for uniform bodies), g from gravity."""
import jax.numpy as jnp

from ..rows import take
from .base import register, wrenches


@register("buoyancy", ("body",), central=True)
def buoyancy(model, site, p, ctx):
    vol = take(ctx.prm["volume"], site.bodies)
    F = -p["fluid_density"] * vol[:, None] * ctx.gravity[None, :]
    return wrenches(model, ctx, site.bodies, F)
