"""buoyancy: F = -rho V g at the centre of volume (= COM for uniform bodies), g from gravity."""
import jax.numpy as jnp

from .base import register, wrenches


@register("buoyancy", ("body",))
def buoyancy(model, site, p, ctx):
    vol = ctx.prm["volume"][jnp.asarray(site.bodies)]
    F = -p["fluid_density"] * vol[:, None] * ctx.gravity[None, :]
    return wrenches(ctx, site.bodies, F)
