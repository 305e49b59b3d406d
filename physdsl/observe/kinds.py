"""Observation kinds (``observe TARGET.KIND from ...``) by name: what a measurement of that
kind reads off a rollout, its data columns and SI unit, and its residual geometry.

Each kind is defined once, where it is registered: the built-ins in ``trajectory.py``; a
plug-in registers its own with ``@observation_kind`` (or ``register_kind``) in one module named
by an entry point of group ``physdsl.observations``. Everything else reads the kind from here:
the language (``syntax/observations.py``: the target it is measured on, markers, columns, unit;
``syntax/sensor.py``: whether offset and gain apply), the compiled model, the check report and
the diagnosis (which kinds get sensor-fault candidates).
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
    normalise: bool = False  # a unit quaternion: renormalised after interpolation, no offset/gain
    marker_source: str | None = None  # Rollout field for a marker's, None: no marker has it
    read: Callable | None = None  # (T, D_source) track -> (T, ncols); None: the track itself
    residual_unit: str | None = None  # unit of the residual, where not ``unit`` (orientation)
    fault_candidates: bool = True  # the diagnosis tries sensor faults (offset, ...) on it

    @property
    def target(self) -> str:
        """What is observed: "body" (also markers, with ``marker_source``) or "joint"."""
        return self.source.split("_")[0]

    @property
    def affine(self) -> bool:
        """An offset or a gain applies (not to a rotation)."""
        return not self.normalise


OBSERVATION_KINDS: Registry[ObservationKind] = Registry("physdsl.observations",
                                                        "observation kind")


def register_kind(name: str, kind: ObservationKind, origin: str = "") -> ObservationKind:
    """Make ``observe TARGET.name`` available."""
    return OBSERVATION_KINDS.add(name, kind, origin)


def observation_kind(name: str, source: str, columns: tuple[str, ...], unit: str,
                     axes: tuple[str, ...] | None = None, **options):
    """Decorator registering ``read`` ((T, D) track of the rollout field ``source`` -> (T,
    len(columns))) as the observation kind ``name``; ``options``: the other fields of
    ``ObservationKind`` (``residual``, ``marker_source``, ...)."""
    def deco(read):
        register_kind(name, ObservationKind(source, len(columns), tuple(axes or columns),
                                            tuple(columns), unit, read=read, **options),
                      read.__module__)
        return read
    return deco
