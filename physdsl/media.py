"""The fluid a scene moves in (``world { medium: air }``): density and dynamic viscosity at
20 °C, which set the physical scale of drag (Stokes 6πμr, quadratic ½ρC_dA)."""
from __future__ import annotations

from typing import NamedTuple


class Medium(NamedTuple):
    density: float  # kg/m^3
    viscosity: float  # Pa s


MEDIA = {"air": Medium(1.204, 1.81e-5), "water": Medium(998.0, 1.0e-3), "vacuum": Medium(0.0, 0.0)}
DEFAULT = "air"
