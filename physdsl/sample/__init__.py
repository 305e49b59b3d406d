"""Sampling a (proto-)program: N concrete scenes, their simulated trajectories, a parameter table.

``sample`` draws every unknown from its prior (for an exported proto-program: the fitted
posterior), writes each draw as a fully concrete .phys file, simulates it, and writes the
trajectories in the same long CSV format measurements are read in, so a generated scene
can be fitted again unchanged. Rooms: ``values`` (every parameter's value per draw, a draw's
concrete text), ``files`` (CSV and frames of a generated scene), ``draw`` (the command).
"""
from __future__ import annotations

from .draw import SampleResult, sample
from .files import JOINT_COLUMNS, TRAJECTORY_COLUMNS, joints_csv, trajectory_csv
from .values import Z_NAME, concrete_text, derived_fields, expression_value, parameter_values

__all__ = ["sample", "SampleResult", "parameter_values", "derived_fields", "concrete_text",
           "expression_value", "trajectory_csv", "joints_csv", "TRAJECTORY_COLUMNS", "JOINT_COLUMNS",
           "Z_NAME"]
