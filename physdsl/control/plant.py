"""The system a controller drives (``physdsl mpc --plant``): a small interface any Python object
can meet, and how a ``--plant`` argument names one.

A plant has ``period`` (s, how long each ``step`` lasts), ``reset() -> Observation`` (its
state at the start) and ``step(u) -> Observation`` (apply the forces ``u`` for one period:
``{target: value}`` in SI, the target being the joint or body a scene's control acts on). An
Observation gives each joint's coordinate (rad or m) and velocity by the scene's joint names.
The controller reads nothing else: a plant's physical parameters stay hidden from it.

``plant_spec.load_plant`` turns a ``--plant`` argument into one.
"""
from __future__ import annotations

from typing import Mapping, NamedTuple, Protocol


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
