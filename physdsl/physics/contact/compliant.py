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
+ eps^2), i.e. Coulomb with a viscous core of width eps; |ft| <= mu fn always.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp


class CompliantSettings(NamedTuple):
    """time_constant (s), gap smoothing length (m), friction velocity smoothing eps (m/s)."""

    time_constant: float = 0.01
    smoothing: float = 1e-4
    friction_eps: float = 1e-3


COMPLIANT_SETTINGS = CompliantSettings()


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


def compliant_forces(dist, vn, vt, mu, e, mass_eff, settings: CompliantSettings = COMPLIANT_SETTINGS):
    """Normal force magnitudes fn (C,) and friction forces ft (C,3) of C contacts.

    dist (C,) signed gap; vn (C,) normal relative velocity (positive separating); vt (C,3)
    tangential relative velocity; mu, e, mass_eff (C,) friction, restitution, effective mass.
    """
    s = settings.smoothing
    omega = jnp.pi / settings.time_constant
    k = mass_eff * omega ** 2
    c = 2.0 * damping_ratio(e) * mass_eff * omega
    x = s * jax.nn.softplus(-dist / s)
    touching = jax.nn.sigmoid(-dist / s)
    fn = jnp.maximum(k * x - c * vn * touching, 0.0)
    speed = jnp.sqrt(jnp.sum(vt * vt, axis=-1) + settings.friction_eps ** 2)
    ft = -(mu * fn / speed)[:, None] * vt
    return fn, ft
