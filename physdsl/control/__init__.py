"""Using a fitted model: choose control sequences or other decisions so a goal is met
(``physdsl control``), robust to what a posterior leaves uncertain."""
from .problem import ControlProblem, build
from .solve import Plan, optimise

__all__ = ["ControlProblem", "Plan", "build", "optimise"]
