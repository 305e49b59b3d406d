"""physdsl: a probabilistic programming language for physical scenes.

Public API: the functions of ``physdsl.api`` (``load`` -> Scene, ``compile`` -> Model,
``infer``, ``check``, ``diagnose``, ``refine``, ``add_effect``, ``design_experiment``,
``render``, ``track``, ``export``, ``sample``), ``parse``, ``Model``, ``Scene`` and the error types. Physics and gradient work
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

from .compile import Model  # noqa: E402
from .syntax import parse  # noqa: E402  (.phys text -> AST)

__all__ += ["Model", "parse"]

# The api floor: plain functions over Scene, Model and posterior values. ``infer``, ``diagnose``,
# ``export``, ``sample``, ``render`` and ``track`` here are these functions; the subpackages of
# the same names stay importable as ``from physdsl.infer.run import ...`` and so on.
from . import api  # noqa: E402
from .api import (  # noqa: E402,A004
    add_effect, beyond_library, check, compile, control, design_experiment, diagnose, export, export_mjcf,
    format_source, import_model, infer, load, mpc, read_run, refine, render, render_draws, sample,
    track,
)

__all__ += list(api.__all__) + ["api"]
