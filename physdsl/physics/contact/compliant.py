"""Compliant (penalty) contact: a smooth spring-damper normal force and smoothed Coulomb friction.

Normal force on the penetration x = s softplus(-dist/s) (a softplus-smoothed gap, so
gradients exist across touch-down), with a linear spring-dashpot tuned per contact from its
effective mass m:

    k = m w^2,  c = 2 zeta m w,  w = pi / time_constant,
    fn = max(k x - c vn g, 0),   g = sigmoid(-dist/s) (the dashpot acts only while touching).

``time_constant`` is the duration of an undamped impact. The force never pulls (fn >= 0), so
contact ends when k x + c (-vn) reaches 0, before x = 0; for that clamped linear dashpot the
coefficient of restitution is (Schwager & Poeschel 2007, derived in ``_log_restitution``)

    e(zeta) = exp(-zeta phi / s),  s = sqrt(1 - zeta^2), phi = atan2(2 zeta s, 2 zeta^2 - 1)  (zeta < 1)
    e(zeta) = (zeta + s')^(-2 zeta / s'),  s' = sqrt(zeta^2 - 1)                               (zeta > 1)

and ``damping_ratio`` inverts it, so the model rebounds with restitution e (up to the gap
smoothing and gravity acting during the short contact). Friction: ft = -mu fn vt / sqrt(|vt|^2
+ eps^2), i.e. Coulomb with a viscous core of width eps; |ft| <= mu fn always. That core is a
damper of rate mu fn w / eps (w: the tangential inverse effective mass), integrated explicitly:
where one step of it more than stops the slip, the slip flips sign every step (a ball rolling
or a box at rest, mu 0.2-0.5, 1 ms steps: 99 flips in 99 steps; a box's d x / d v0 came out
-1.9 where finite differences give 0.10). With a ``FrictionStep``, eps is widened to the slip
one explicit step of the pair's whole friction makes (``step_width``).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..step_width import step_width


class CompliantSettings(NamedTuple):
    """time_constant (s), gap smoothing length (m), friction velocity smoothing eps (m/s)."""

    time_constant: float = 0.01
    smoothing: float = 1e-4
    friction_eps: float = 1e-3


COMPLIANT_SETTINGS = CompliantSettings()


class FrictionStep(NamedTuple):
    """What widens the friction's eps for an explicit step: step length h (s), an upper bound
    of each contact's tangential inverse effective mass (C,) (1/kg), which contacts carry
    force (C,) bool, and each contact's pair (C,) (static ints: the rows of a pair add their
    friction, as they act on the same bodies)."""

    h: float
    inv_mass_t: jnp.ndarray
    active: jnp.ndarray
    pair: np.ndarray


def _log_restitution(zeta):
    """ln e of the clamped linear spring-dashpot with damping ratio zeta >= 0 (see module)."""
    zeta = jnp.where(jnp.abs(zeta - 1.0) < 1e-7, 1.0 - 1e-7, zeta)
    under = zeta < 1.0
    s = jnp.sqrt(jnp.where(under, 1.0 - zeta ** 2, 1.0))
    phi = jnp.arctan2(2 * zeta * s, 2 * zeta ** 2 - 1)
    sp = jnp.sqrt(jnp.where(under, 1.0, zeta ** 2 - 1.0))
    return jnp.where(under, -zeta * phi / s, -2 * zeta * jnp.log(zeta + sp) / sp)


def damping_ratio(e):
    """Damping ratio zeta giving restitution e (elementwise, e clipped to [1e-6, 1]).

    Bisection on the monotone ln e(zeta), then one Newton step from the (non-differentiated)
    bisection result, which makes d zeta / d e the implicit-function derivative.
    """
    target = jnp.log(jnp.clip(e, 1e-6, 1.0))

    def body(_, lohi):
        lo, hi = lohi
        mid = 0.5 * (lo + hi)
        above = _log_restitution(mid) > target  # e(mid) too large: need more damping
        return jnp.where(above, mid, lo), jnp.where(above, hi, mid)

    lo, hi = jax.lax.fori_loop(0, 80, body, (jnp.zeros_like(target), jnp.full_like(target, 1e3)))
    z0 = jax.lax.stop_gradient(0.5 * (lo + hi))
    slope = jax.vmap(jax.grad(_log_restitution))(jnp.ravel(z0)).reshape(z0.shape)
    return jnp.maximum(z0 - (_log_restitution(z0) - target) / slope, 0.0)


def compliant_forces(dist, vn, vt, mu, e, mass_eff, settings: CompliantSettings = COMPLIANT_SETTINGS,
                     step: FrictionStep | None = None):
    """Normal force magnitudes fn (C,) and friction forces ft (C,3) of C contacts.

    dist (C,) signed gap; vn (C,) normal relative velocity (positive separating); vt (C,3)
    tangential relative velocity; mu, e, mass_eff (C,) friction, restitution, effective mass;
    ``step``: widen the friction's eps for an explicit step (see the module).
    """
    s = settings.smoothing
    omega = jnp.pi / settings.time_constant
    k = mass_eff * omega ** 2
    c = 2.0 * damping_ratio(e) * mass_eff * omega
    x = s * jax.nn.softplus(-dist / s)
    touching = jax.nn.sigmoid(-dist / s)
    fn = jnp.maximum(k * x - c * vn * touching, 0.0)
    eps = settings.friction_eps
    if step is not None:
        load = jnp.where(step.active, mu * fn, 0.0)
        load = jax.ops.segment_sum(load, step.pair, num_segments=int(np.max(step.pair)) + 1)[step.pair]
        eps = step_width(eps, step.h, load, step.inv_mass_t)
    speed = jnp.sqrt(jnp.sum(vt * vt, axis=-1) + eps ** 2)
    ft = -(mu * fn / speed)[:, None] * vt
    return fn, ft
