"""Observation kinds (``observe TARGET.KIND from ...``) by name: what a measurement of that
kind reads off a rollout, its data columns and SI unit, and its residual geometry.

Built-in kinds are registered in ``trajectory.py``; a plug-in registers its own with
``register_kind`` (entry-point group ``physdsl.observations``). The language (``syntax/
observations.py``) reads the columns and unit from here, the compiled model the rest.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

from ..registry import Registry


def subtract(predicted, measured):
    """measured - predicted: the residual of quantities in a vector space."""
    return measured - predicted


class ObservationKind(NamedTuple):
    """One observable quantity; indexable as the former table's tuple (source, ncols, axes,
    columns, unit), which the language reads."""

    source: str  # Rollout field of a body/joint ("body_pos", "joint_vel", ...): body_* or joint_*
    ncols: int  # measured components
    axes: tuple[str, ...]  # residual components (orientation: 3 for a 4-column quaternion)
    columns: tuple[str, ...]  # the data file's columns
    unit: str  # SI unit (a slider's joint quantities read rad as m)
    residual: Callable = subtract  # (predicted, measured) -> residual (N, len(axes))
    normalise: bool = False  # predictions renormalised after interpolation (quaternions)
    marker_source: str | None = None  # Rollout field for a marker's, None: no marker has it


OBSERVATION_KINDS: Registry[ObservationKind] = Registry("physdsl.observations",
                                                        "observation kind")


def register_kind(name: str, kind: ObservationKind, origin: str = "") -> ObservationKind:
    """Make ``observe TARGET.name`` available."""
    return OBSERVATION_KINDS.add(name, kind, origin)
