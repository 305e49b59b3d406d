"""damper: F = -c (dl/dt) along the line between anchor and attachment (see spring)."""
import jax.numpy as jnp

from ..kinematics import point_velocity
from ..spatial import normalize
from .base import register, wrench
from .spring import endpoints


@register("damper", ("body", "pair"))
def damper(model, site, p, ctx):
    a, xa, b, xb = endpoints(site, p, ctx)
    u = normalize(xb - xa)
    va = point_velocity(ctx.kin, a, xa) if a is not None else jnp.zeros(3)
    rate = jnp.dot(u, point_velocity(ctx.kin, b, xb) - va)
    F = -p["coefficient"] * rate * u
    load = wrench(model, ctx, b, F, xb)
    return load if a is None else load + wrench(model, ctx, a, -F, xa)
