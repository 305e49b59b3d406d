"""What a sensor reports: ``gain * pred(t - delay) + offset`` of the modelled quantity.

The delay reads the rollout at the shifted times by linear interpolation on its uniform grid
(the grid rows are chosen without gradient, the blend weight carries the delay's derivative);
the gain and offset act in the quantity's own components (an angle's offset is added, and the
residual still wraps). Orientations take only a delay (renormalised, like ``predict``).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..expr import evaluate
from ..scene import Observation
from . import trajectory


def delayed(track, grid: np.ndarray, times: np.ndarray, delay):
    """``track`` (T, D) on the uniform ``grid`` read at ``times - delay`` (clamped to the grid)."""
    n = track.shape[0]
    dt = float(grid[1] - grid[0]) if len(grid) > 1 else 1.0
    pos = jnp.clip((jnp.asarray(times) - delay - float(grid[0])) / dt, 0.0, n - 1.0)
    lo = jnp.clip(jnp.floor(jax.lax.stop_gradient(pos)), 0, max(n - 2, 0)).astype(jnp.int32)
    w = (pos - lo)[:, None]
    return track[lo] * (1 - w) + track[jnp.minimum(lo + 1, n - 1)] * w


def predict(rollout, simulator, obs: Observation, interp: trajectory.Interpolation, values):
    """Prediction of ``obs`` at its measurement times, through its sensor terms: (N, D)."""
    s = obs.sensor
    if s is None:
        return trajectory.predict(rollout, simulator, obs, interp)
    if s.delay is not None:
        track = trajectory.model_track(rollout, simulator, obs)
        out = delayed(track, np.asarray(simulator.times), obs.times, evaluate(s.delay, values))
        if obs.quantity == "orientation":
            out = out / jnp.linalg.norm(out, axis=-1, keepdims=True)
    else:
        out = trajectory.predict(rollout, simulator, obs, interp)
    if s.gain is not None:
        out = evaluate(s.gain, values) * out
    if s.offset is not None:
        out = out + evaluate(s.offset, values)
    return out


def terms(obs: Observation) -> dict:
    """name -> SI expression of the sensor terms ``obs`` has."""
    s = obs.sensor
    if s is None:
        return {}
    return {k: getattr(s, k) for k in ("offset", "gain", "delay") if getattr(s, k) is not None}
