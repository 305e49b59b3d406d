"""Measurements: reading them, predicting them from a rollout, and their likelihood.

Importing the package registers the built-in observation kinds (``trajectory``) and sensor
faults (``sensor``)."""
from . import sensor, trajectory  # noqa: F401 - registers the built-in kinds and faults
