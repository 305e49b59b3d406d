"""Experiment design: the setting of what a user can change that best tells models apart."""
