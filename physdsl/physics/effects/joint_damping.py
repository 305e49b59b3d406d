"""joint_damping: tau = -b qdot on every dof of a joint (viscous)."""
from .base import joint_forces, joint_velocity, register


@register("joint_damping", ("joint",))
def joint_damping(model, site, p, ctx):
    return joint_forces(model, site, -p["coefficient"] * joint_velocity(ctx, site))
