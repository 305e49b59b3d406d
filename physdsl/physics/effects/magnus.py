"""magnus: lift F = S omega x v on a spinning body, at its centre of mass."""
import jax.numpy as jnp

from ..rows import take
from .base import com_velocity, register, wrenches


@register("magnus", ("body",))
def magnus(model, site, p, ctx):
    w = take(ctx.kin.ang, site.bodies)
    return wrenches(model, ctx, site.bodies, p["coefficient"] * jnp.cross(w, com_velocity(ctx, site.bodies)))
