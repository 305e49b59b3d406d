"""quadratic_drag: F = -c |v| v at the centre of mass (blunt-body air drag)."""
from ..spatial import safe_norm
from .base import com_velocity, register, wrenches


@register("quadratic_drag", ("body",), central=True)
def quadratic_drag(model, site, p, ctx):
    v = com_velocity(ctx, site.bodies)
    return wrenches(model, ctx, site.bodies, -p["coefficient"] * safe_norm(v, keepdims=True) * v)
