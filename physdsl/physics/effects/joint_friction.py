"""joint_friction: Coulomb friction smoothed as tau = -T tanh(qdot / smoothing).

The tanh replaces sign(qdot): within |qdot| < smoothing the torque ramps linearly (slope
T/smoothing), so a joint at rest creeps slowly instead of sticking exactly; gradients exist.
"""
import jax.numpy as jnp

from .base import joint_forces, joint_velocity, register


@register("joint_friction", ("joint",))
def joint_friction(model, site, p, ctx):
    qd = joint_velocity(ctx, site)
    return joint_forces(model, site, -p["torque"] * jnp.tanh(qd / p.get("smoothing", 0.01)))
