"""wind: the change in quadratic drag when the air moves at w: F = c(|w-v|(w-v) + |v|v).

Drag in moving air is c|w-v|(w-v); still-air drag -c|v|v is quadratic_drag's job, so this
effect adds the difference, which is exactly 0 at w = 0. (docs/language.md prints the second
term with a minus sign; that would not vanish at the off value.)
"""
from ..spatial import safe_norm
from .base import com_velocity, register, wrenches


@register("wind", ("body",), central=True)
def wind(model, site, p, ctx):
    v = com_velocity(ctx, site.bodies)
    rel = p["velocity"][None, :] - v
    F = p["coefficient"] * (safe_norm(rel, keepdims=True) * rel + safe_norm(v, keepdims=True) * v)
    return wrenches(model, ctx, site.bodies, F)
