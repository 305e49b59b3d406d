"""rolling_resistance: torque of size l N opposing the relative angular velocity about axes in
the contact plane, l the coefficient (m) and N the pair's normal force from the previous step.

The direction w/|w| is smoothed as w / sqrt(|w|^2 + eps^2), so the torque vanishes
continuously when rolling stops. Near w = 0 that is a damper of rate l N / eps, applied
explicitly (the torque at the step's start). Where one step of it would more than stop the
rotation (h l N / (eps I) > 1), the step overshoots: a sign-flipping oscillation grows by
|1 - h l N / (eps I)| per step until |w| ~ eps (x2.5 per step for a pool ball at rest; its
position moves by < 1e-8 m, but its derivatives reach 1e9 m/s per unit of the unknowns).
So eps^2 = EPS^2 + (h l N / I_min)^2: the smoothing is never narrower than the change of
angular velocity one step of the whole torque makes (I_min: a lower bound of the inertia any
torque on the pair meets), and each step shrinks w without flipping it. Rolling at |w| well
above that change is unchanged to a relative (eps / |w|)^2 / 2.
"""
import jax.numpy as jnp

from ..rows import take
from ..step_width import step_inverse_inertia, step_width
from .base import register, wrenches, zero_load

EPS = 1e-3  # rad/s


@register("rolling_resistance", ("pair",))
def rolling_resistance(model, site, p, ctx):
    a, b = site.bodies
    if not site.contacts:
        return zero_load(model)
    N = take(ctx.contact_force, site.contacts)
    n = take(ctx.contact_normal, site.contacts)
    w = ctx.kin.ang[a] - ctx.kin.ang[b]
    wh = w[None, :] - jnp.sum(n * w[None, :], -1, keepdims=True) * n  # (K, 3) in-plane part
    h = model.dt / model.substeps
    eps = step_width(EPS, h, p["coefficient"] * jnp.sum(N), step_inverse_inertia(model, ctx.prm, (a, b)))
    T = -p["coefficient"] * N[:, None] * wh / jnp.sqrt(jnp.sum(wh * wh, -1, keepdims=True) + eps**2)
    T = jnp.sum(T, 0)
    return wrenches(model, ctx, (a, b), jnp.zeros((2, 3)), torques=jnp.stack([T, -T]))
