"""quadratic_drag: F = -c |v| v at the centre of mass (blunt-body air drag)."""
import jax
import jax.numpy as jnp

from .base import com_velocity, register, wrenches


@jax.custom_jvp
def speed_times(v):
    """|v| v per row of v (n, 3): the quadratic drag direction and size, with the derivative
    |v| dv + v (v . dv) / |v|, which is 0 at v = 0.

    Its own derivative rule, rather than a norm guarded against v = 0 (``safe_norm``): the guard's
    selects around the square root split every RK4 stage's tangents into extra kernels.
    """
    return jnp.sqrt(jnp.sum(v * v, axis=-1, keepdims=True)) * v


@speed_times.defjvp
def _speed_times_jvp(primals, tangents):
    (v,), (dv,) = primals, tangents
    n = jnp.sqrt(jnp.sum(v * v, axis=-1, keepdims=True))
    dn = jnp.sum(v * dv, axis=-1, keepdims=True) / jnp.where(n > 0, n, 1.0)
    return n * v, n * dv + dn * v


@register("quadratic_drag", ("body",), central=True)
def quadratic_drag(model, site, p, ctx):
    v = com_velocity(ctx, site.bodies)
    return wrenches(model, ctx, site.bodies, -p["coefficient"] * speed_times(v))
