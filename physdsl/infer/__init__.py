"""Inference: backends behind one interface, run with checkpoints into arviz InferenceData."""
from .base import BACKENDS, Backend, Settings, get_backend, register_backend  # noqa: F401
from . import backends  # noqa: F401,E402 - registers the built-in backends
