"""Measurements: reading them, predicting them from a rollout, and their likelihood."""
