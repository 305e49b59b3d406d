"""linear_drag: F = -b v at the centre of mass (Stokes drag)."""
from .base import com_velocity, register, wrenches


@register("linear_drag", ("body",), central=True)
def linear_drag(model, site, p, ctx):
    return wrenches(model, ctx, site.bodies, -p["coefficient"] * com_velocity(ctx, site.bodies))
