"""spring: F = -k (l - l0) along the spring, between a world anchor (or a point of the first
body of a pair, in its frame) and an attachment point in the (second) body's frame."""
import jax.numpy as jnp

from ..spatial import normalize
from .base import register, wrench


def endpoints(site, p, ctx):
    """(first body or None, world point on it, second body, world attachment point)."""
    kin = ctx.kin
    att = p.get("attachment", jnp.zeros(3))
    if len(site.bodies) == 2:
        a, b = site.bodies
        xa = kin.pos[a] + kin.rot[a] @ p["anchor"]
    else:
        a, b = None, site.bodies[0]
        xa = p["anchor"]
    xb = kin.pos[b] + kin.rot[b] @ att
    return a, xa, b, xb


@register("spring", ("body", "pair"))
def spring(model, site, p, ctx):
    a, xa, b, xb = endpoints(site, p, ctx)
    d = xb - xa
    # -k (l - l0) d/l written without dividing by l, so it is smooth at l = 0 when l0 = 0
    F = -p["stiffness"] * (d - p.get("rest_length", 0.0) * normalize(d))
    load = wrench(model, ctx, b, F, xb)
    return load if a is None else load + wrench(model, ctx, a, -F, xa)
