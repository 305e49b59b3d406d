"""physdsl: a probabilistic programming language for physical scenes.

Public API: ``load``, ``parse``, ``compile`` and the error types. Physics and gradient work
runs in float64 by default; set ``PHYSDSL_FLOAT32=1`` to trade accuracy for speed.
"""
from __future__ import annotations

import os
import warnings

import jax

# arviz 0.2x announces its coming refactor on import; it is not news to our users.
warnings.filterwarnings("ignore", message="ArviZ is undergoing", category=FutureWarning)

if os.environ.get("PHYSDSL_FLOAT32", "") not in ("1", "true", "yes"):
    jax.config.update("jax_enable_x64", True)

from . import cache as _cache  # noqa: E402

_cache.configure()  # compiled programs persist across runs (PHYSDSL_CACHE_DIR=off: not)

from .errors import (  # noqa: E402
    DataError, InferenceError, ModelError, PhysError, PhysErrors, PhysImportError,
    PhysNameError, PhysStructureError, PhysSyntaxError, PhysTypeError, PhysUnitError, Span,
    UsageError,
)
from .scene import Scene  # noqa: E402

from .version import __version__  # noqa: E402

__all__ = [
    "DataError", "InferenceError", "ModelError", "PhysError", "PhysErrors", "PhysImportError",
    "PhysNameError", "PhysStructureError", "PhysSyntaxError", "PhysTypeError", "PhysUnitError",
    "Scene", "Span", "UsageError", "__version__",
]

from .syntax import format_source, load, parse  # noqa: E402  (the .phys language)

__all__ += ["format_source", "load", "parse"]

from .compile import Model  # noqa: E402
from .compile import compile as compile  # noqa: E402,A001  (text or path -> Model)
from .diagnose.refine import refine  # noqa: E402

__all__ += ["Model", "compile", "refine"]
