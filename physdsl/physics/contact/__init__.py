"""Contact for the differentiable physics engine.

- ``detect``: fixed-size contact candidates between primitive shapes (``detect.py``);
- ``solve_lcp_step``: one velocity step with contact and polyhedral Coulomb friction as an LCP,
  solved by a primal-dual interior-point method and differentiated implicitly (``step.py``,
  ``lcp.py``);
- ``compliant_forces``: a smooth penalty spring-damper alternative (``compliant.py``).
"""
from .compliant import (COMPLIANT_SETTINGS, CompliantSettings, FrictionStep, compliant_forces,
                        damping_ratio)
from .detect import PAIRS, SHAPE_CODES, ContactPoints, contact_count, contact_margin, detect
from .lcp import IP_SETTINGS, IPSettings, lcp_residual, lcp_solve, lcp_solve_warm
from .step import (LCP_SETTINGS, ContactLCP, ContactStep, Impacts, LCPSettings, build_lcp,
                   impact_time, impacts, lcp_size, normal_target, restitution_threshold,
                   solve_lcp_step)

__all__ = [
    "COMPLIANT_SETTINGS", "CompliantSettings", "ContactLCP", "ContactPoints", "ContactStep",
    "FrictionStep",
    "IPSettings", "Impacts", "impact_time", "impacts",
    "IP_SETTINGS", "LCPSettings", "LCP_SETTINGS", "PAIRS", "SHAPE_CODES", "build_lcp",
    "compliant_forces", "contact_count", "contact_margin", "damping_ratio", "detect",
    "lcp_residual", "lcp_size", "lcp_solve", "lcp_solve_warm", "normal_target",
    "restitution_threshold", "solve_lcp_step",
]
