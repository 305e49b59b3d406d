"""How ``physdsl mpc --plant`` names a plant (``plant.Plant``): an MJCF file (``*.xml``:
``mujoco_plant.MujocoPlant``, mujoco needed) or a Python entry point ``package.module:factory``
(a callable returning a plant, given the keyword options the command passes: ``period``,
``initial``, ``seed``)."""
from __future__ import annotations

import importlib
from pathlib import Path

from ..errors import UsageError
from .mujoco_plant import MujocoPlant
from .plant import Plant


def check_plant_spec(spec: str | Path) -> None:
    """A usage error for a ``--plant`` that names no MJCF file and no entry point."""
    text = str(spec)
    if text.endswith(".xml"):
        if not Path(text).is_file():
            raise UsageError(f"plant file '{text}' not found", hint="give an MJCF file or "
                             "a Python entry point 'package.module:factory'")
    elif not all(text.partition(":")[::2]):
        raise UsageError(f"plant '{text}' is neither an MJCF file (.xml) nor an entry point",
                         hint="write 'package.module:factory'")


def load_plant(spec: str | Path, **options) -> Plant:
    """The plant named by ``spec``: an MJCF path or ``module:factory`` (``options`` passed on)."""
    check_plant_spec(spec)
    text = str(spec)
    if text.endswith(".xml"):
        return MujocoPlant(text, **options)
    module, _, attr = text.partition(":")
    try:
        factory = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise UsageError(f"cannot load plant '{text}': {exc}",
                         hint="the module must be importable and define the factory") from None
    return factory(**options)
