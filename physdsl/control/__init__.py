"""Using a fitted model: choose control sequences or other decisions so a goal is met
(``physdsl control``, ``physdsl design``), robust to what a posterior leaves uncertain; and
drive a plant in closed loop, refitting the model as it goes (``physdsl mpc``)."""
from .mpc import Controller, MpcResult, run
from .plant import Plant
from .problem import ControlProblem, build
from .solve import Plan, optimise

__all__ = ["ControlProblem", "Controller", "MpcResult", "Plan", "Plant", "build", "optimise", "run"]
