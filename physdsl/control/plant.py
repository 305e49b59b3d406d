"""The system a controller drives (``physdsl mpc --plant``): a small interface any Python object
can meet, and how a ``--plant`` argument names one.

A plant has ``period`` (s, how long each ``step`` lasts), ``reset() -> Observation`` (its
state at the start) and ``step(u) -> Observation`` (apply the forces ``u`` for one period:
``{target: value}`` in SI, the target being the joint or body a scene's control acts on). An
Observation gives each joint's coordinate (rad or m) and velocity by the scene's joint names.
The controller reads nothing else: a plant's physical parameters stay hidden from it.

``--plant`` is an MJCF file (``*.xml``: ``mujoco_plant.MujocoPlant``, mujoco needed) or a
Python entry point ``package.module:factory`` (a callable returning a plant, given the
keyword options the command passes: ``period``, ``initial``, ``seed``).
"""
from __future__ import annotations

import importlib
from pathlib import Path
from typing import Mapping, NamedTuple, Protocol

from ..errors import UsageError


class Observation(NamedTuple):
    """A plant's state at time ``t`` (s): joint name -> coordinate and velocity (SI)."""

    t: float
    position: Mapping[str, float]
    velocity: Mapping[str, float]


class Plant(Protocol):
    """What ``physdsl mpc`` drives."""

    period: float

    def reset(self) -> Observation: ...

    def step(self, u: Mapping[str, float]) -> Observation: ...


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
        from .mujoco_plant import MujocoPlant  # mujoco is an optional extra

        return MujocoPlant(text, **options)
    module, _, attr = text.partition(":")
    try:
        factory = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise UsageError(f"cannot load plant '{text}': {exc}",
                         hint="the module must be importable and define the factory") from None
    return factory(**options)
