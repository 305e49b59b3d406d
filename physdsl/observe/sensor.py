"""What a sensor reports: ``gain * pred(t - delay) + offset`` of the modelled quantity.

The delay reads the rollout at the shifted times by linear interpolation on its uniform grid
(the grid rows are chosen without gradient, the blend weight carries the delay's derivative);
the gain and offset act in the quantity's own components (an angle's offset is added, and the
residual still wraps). Orientations take only a delay (renormalised, like ``predict``).

Each term is a sensor fault registered in ``SENSOR_FAULTS`` (entry-point group
``physdsl.sensor_faults``) with its exact ("off") value and unit; a fault that acts on the
reading time is applied first, then those on the value in the order they were registered.
A fault is defined once, by its ``@sensor_fault``: the language reads its name, unit and
constraints from it (``syntax/sensor.py``), the diagnosis its off value and unit (its candidates,
priors and score columns).
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..expr import evaluate
from ..registry import Registry
from ..scene import Observation
from . import trajectory
from .kinds import OBSERVATION_KINDS


class SensorFault(NamedTuple):
    """A term of a sensor: ``apply(out, value)`` on the predicted values, or with ``on_time``
    ``apply(track, grid, times, value)`` on the reading times of the rollout's track."""

    apply: Callable
    off: float  # the value of an exact sensor
    unit: str | None  # SI unit of the term; None: the observed quantity's own
    on_time: bool = False
    rotations: bool = False  # also for orientations (an offset or gain is not a rotation)
    per_axis: bool = False  # one number or one per axis of the quantity (else one number)
    positive: bool = False  # a constant value must be > 0


SENSOR_FAULTS: Registry[SensorFault] = Registry("physdsl.sensor_faults", "sensor fault")


def sensor_fault(name: str, off: float, unit: str | None, on_time: bool = False,
                 rotations: bool = False, per_axis: bool = False, positive: bool = False):
    """Decorator registering ``apply`` as the sensor fault ``name`` (``observe X.Q { name: ...}``)."""
    def deco(fn):
        SENSOR_FAULTS.add(name, SensorFault(fn, off, unit, on_time, rotations, per_axis,
                                            positive), fn.__module__)
        return fn
    return deco


@sensor_fault("delay", 0.0, "s", on_time=True, rotations=True)
def delayed(track, grid: np.ndarray, times: np.ndarray, delay):
    """``track`` (T, D) on the uniform ``grid`` read at ``times - delay`` (clamped to the grid)."""
    n = track.shape[0]
    dt = float(grid[1] - grid[0]) if len(grid) > 1 else 1.0
    pos = jnp.clip((jnp.asarray(times) - delay - float(grid[0])) / dt, 0.0, n - 1.0)
    lo = jnp.clip(jnp.floor(jax.lax.stop_gradient(pos)), 0, max(n - 2, 0)).astype(jnp.int32)
    w = (pos - lo)[:, None]
    return track[lo] * (1 - w) + track[jnp.minimum(lo + 1, n - 1)] * w


@sensor_fault("gain", 1.0, "1", positive=True)
def gain(out, g):
    return g * out


@sensor_fault("offset", 0.0, None, per_axis=True)
def offset(out, c):
    return out + c


def predict(rollout, simulator, obs: Observation, interp: trajectory.Interpolation, values):
    """Prediction of ``obs`` at its measurement times, through its sensor terms: (N, D)."""
    present = terms(obs)
    timed = [k for k in present if SENSOR_FAULTS[k].on_time]
    if timed:
        track = trajectory.model_track(rollout, simulator, obs)
        out = SENSOR_FAULTS[timed[0]].apply(track, np.asarray(simulator.times), obs.times,
                                           evaluate(present[timed[0]], values))
        if OBSERVATION_KINDS[obs.quantity].normalise:
            out = out / jnp.linalg.norm(out, axis=-1, keepdims=True)
    else:
        out = trajectory.predict(rollout, simulator, obs, interp)
    for k, e in present.items():
        if not SENSOR_FAULTS[k].on_time:
            out = SENSOR_FAULTS[k].apply(out, evaluate(e, values))
    return out


def terms(obs: Observation) -> dict:
    """name -> SI expression of the sensor terms ``obs`` has (in ``SENSOR_FAULTS``' order)."""
    s = obs.sensor
    if s is None:
        return {}
    return {k: s.get(k) for k in SENSOR_FAULTS if s.get(k) is not None}
