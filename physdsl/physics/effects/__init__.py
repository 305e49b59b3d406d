"""Physical effects of the standard library, one module each, registered in ``EFFECTS``."""
from . import (  # noqa: F401  (importing registers)
    buoyancy, constant_force, contact_params, control_force, damper, gravity, joint_damping,
    joint_friction, joint_spring, linear_drag, magnus, quadratic_drag, rolling_resistance,
    spring, wind,
)
from .base import EFFECTS, Ctx, Effect, Load, register, zero_load

__all__ = ["EFFECTS", "Ctx", "Effect", "Load", "register", "zero_load"]
