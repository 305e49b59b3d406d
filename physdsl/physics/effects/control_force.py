"""control_force: a known or unknown force sequence, F(t) = gain * values(t), zero-order hold.

``values[k]`` acts on [times[k], times[k+1]); zero before times[0]; the last value is held.
The lookup uses the start time of the current (sub)step, so a value is held over a whole step
(as a controller writing MuJoCo's ``ctrl`` before each step). On a hinge/slider: a scalar
torque/force per time; on a body: a world force (3,) or force and torque (6,) at the COM.
"""
import jax.numpy as jnp

from ...errors import ModelError
from .base import joint_forces, register, wrench


def hold(times, values, t, dt_tol=1e-9):
    """Zero-order-hold sample of ``values`` at time t (0 before the first time)."""
    k = jnp.searchsorted(times, t + dt_tol, side="right") - 1
    v = values[jnp.clip(k, 0, values.shape[0] - 1)]
    return jnp.where(k >= 0, v, jnp.zeros_like(v))


def _check(scene, use, joint):
    if "times" not in use.tables or ("values" not in use.tables and "values" not in use.params):
        raise ModelError(f"control '{use.key}' has no times or values", span=use.span,
                         hint="give `times` and `values` (or a file with a `t` column)")
    n = len(use.tables["times"])
    vals = use.tables.get("values")
    if vals is not None and (len(vals) != n or (joint is None and (
            getattr(vals, "ndim", 1) != 2 or vals.shape[1] not in (3, 6)))):
        raise ModelError(f"control '{use.key}': values must be (N,) for a joint or (N, 3)/(N, 6) "
                         "for a body, with N = len(times)", span=use.span)


@register("control_force", ("body", "joint"), validate=_check)
def control_force(model, site, p, ctx):
    times = jnp.asarray(site.tables["times"], dtype=float)
    values = p["values"] if "values" in p else jnp.asarray(site.tables["values"], dtype=float)
    u = p.get("gain", 1.0) * hold(times, values, ctx.t_step)
    if site.joint is not None:
        return joint_forces(model, site, jnp.reshape(u, (-1,)) * jnp.ones(len(site.dofs)))
    u = jnp.reshape(u, (-1,))
    return wrench(model, ctx, site.bodies[0], u[:3], torque=u[3:6] if u.shape[0] == 6 else None)
