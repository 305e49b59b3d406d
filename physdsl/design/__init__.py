"""Experiment design: the setting of what a user can change that best tells two models apart
(``experiment``), or that teaches the most about one model's unknowns (``information``,
``excite``); both vary fields through ``vary``."""
