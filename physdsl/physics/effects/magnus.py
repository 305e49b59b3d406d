"""magnus: lift F = S omega x v on a spinning body, at its centre of mass."""
import jax.numpy as jnp

from .base import com_velocity, register, wrenches


@register("magnus", ("body",))
def magnus(model, site, p, ctx):
    w = ctx.kin.vel[jnp.asarray(site.bodies), :3]
    return wrenches(ctx, site.bodies, p["coefficient"] * jnp.cross(w, com_velocity(ctx, site.bodies)))
