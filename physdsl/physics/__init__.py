"""Differentiable rigid-body physics in JAX: a checked Scene in, a pure rollout function out.

``build_simulator(scene)`` builds the static PhysicsModel (tree, joints, effects, contact candidates);
``Simulator.simulate(values)`` evaluates every Expr from the unknowns' values and integrates.
"""
from .model import build_model
from .structure import PhysicsModel
from .simulator import Rollout, Simulator, build_simulator

__all__ = ["PhysicsModel", "Rollout", "Simulator", "build_model", "build_simulator"]
