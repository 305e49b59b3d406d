"""rolling_resistance: torque of size l N opposing the relative angular velocity about axes in
the contact plane, l the coefficient (m) and N the pair's normal force from the previous step.

The direction w/|w| is smoothed as w / sqrt(|w|^2 + eps^2) (eps = 1e-3 rad/s) so the torque
vanishes continuously when rolling stops.
"""
import jax.numpy as jnp

from ..rows import take
from .base import register, wrenches, zero_load

EPS = 1e-3


@register("rolling_resistance", ("pair",))
def rolling_resistance(model, site, p, ctx):
    a, b = site.bodies
    if not site.contacts:
        return zero_load(model)
    N = take(ctx.contact_force, site.contacts)
    n = take(ctx.contact_normal, site.contacts)
    w = ctx.kin.ang[a] - ctx.kin.ang[b]
    wh = w[None, :] - jnp.sum(n * w[None, :], -1, keepdims=True) * n  # (K, 3) in-plane part
    T = -p["coefficient"] * N[:, None] * wh / jnp.sqrt(jnp.sum(wh * wh, -1, keepdims=True) + EPS**2)
    T = jnp.sum(T, 0)
    return wrenches(model, ctx, (a, b), jnp.zeros((2, 3)), torques=jnp.stack([T, -T]))
