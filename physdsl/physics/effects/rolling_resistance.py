"""rolling_resistance: torque of size l N opposing the relative angular velocity about axes in
the contact plane, l the coefficient (m) and N the pair's normal force from the previous step.

The direction w/|w| is smoothed as w / sqrt(|w|^2 + eps^2) (eps = 1e-3 rad/s) so the torque
vanishes continuously when rolling stops.
"""
import jax.numpy as jnp

from .base import register, wrench

EPS = 1e-3


@register("rolling_resistance", ("pair",))
def rolling_resistance(model, site, p, ctx):
    a, b = site.bodies
    if not site.contacts:
        return jnp.zeros(model.nv)
    rows = jnp.asarray(site.contacts)
    N = ctx.contact_force[rows]
    n = ctx.contact_normal[rows]
    w = ctx.kin.vel[a, :3] - ctx.kin.vel[b, :3]
    wh = w[None, :] - jnp.sum(n * w[None, :], -1, keepdims=True) * n  # (K, 3) in-plane part
    T = -p["coefficient"] * N[:, None] * wh / jnp.sqrt(jnp.sum(wh * wh, -1, keepdims=True) + EPS**2)
    T = jnp.sum(T, 0)
    z = jnp.zeros(3)
    return wrench(ctx, a, z, torque=T) + wrench(ctx, b, z, torque=-T)
