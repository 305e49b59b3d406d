"""physdsl: a probabilistic programming language for physical scenes.

Public API: the functions of ``physdsl.api`` (``load`` -> Scene, ``compile`` -> Model,
``infer``, ``check``, ``diagnose``, ``refine``, ``add_effect``, ``design_experiment``,
``render``, ``track``, ``export``, ``sample``), ``parse``, ``Model``, ``Scene`` and the error
types; the api's names are imported on first use. ``physdsl.export`` (and compile, infer,
diagnose, sample, render, track, control) is always the api function, also after
``import physdsl.export.mjcf``: reach a subpackage by ``from physdsl.export import mjcf``.
Physics and gradient work runs in float64 by default; set ``PHYSDSL_FLOAT32=1`` to trade
accuracy for speed.
"""
from __future__ import annotations

import os
import sys as _sys
import types as _types
import warnings
from importlib import import_module as _import

from . import xla_flags as _xla_flags

_xla_flags.configure()  # rollout loops as one kernel (before JAX starts; PHYSDSL_XLA_FLAGS=off: not)

import jax  # noqa: E402

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

# The api floor: plain functions over Scene, Model and posterior values, and ``Model``/``parse``,
# imported on first use (PEP 562), so ``physdsl --help`` and ``physdsl lint`` do not pay for
# inference, diagnosis and control. ``API`` lists ``physdsl.api.__all__`` (a test holds them
# equal).
API = (
    "load", "compile", "infer", "check", "diagnose", "refine", "add_effect", "design_experiment",
    "render", "render_draws", "track", "export", "export_mjcf", "sample", "read_run",
    "import_model", "format_source", "control", "mpc", "beyond_library",
)
_LAZY = {**{name: ".api" for name in API}, "api": None, "Model": ".compile", "parse": ".syntax"}

__all__ += ["Model", "parse", *API, "api"]


def __getattr__(name: str):
    """``physdsl.load``, ``physdsl.Model``, ... : the api's names, imported on first use."""
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = _import(".api" if name == "api" else _LAZY[name], __name__)
    value = module if name == "api" else getattr(module, name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


class _Package(_types.ModuleType):
    """The package object. Several api functions share their name with a subpackage
    (``physdsl.export`` the function, ``physdsl/export/`` the package; also compile, infer,
    diagnose, sample, render, track, control): the import system would rebind
    ``physdsl.export`` to the subpackage when it is first imported. Here the api's name always
    means the function; the subpackages are reached by ``from physdsl.export import mjcf`` or
    ``from physdsl.export.mjcf import ...`` (both read ``sys.modules``)."""

    def __setattr__(self, name: str, value) -> None:
        if name in API and isinstance(value, _types.ModuleType):
            return  # a subpackage being imported: it stays in sys.modules, not on this name
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package
