"""Trajectory measurements: predict them from a rollout at the data's own times, and compare.

Predictions are read off the rollout's uniform time grid by linear interpolation at each
measurement time (quaternions are interpolated and renormalised); the interpolation weights
are static numpy arrays computed once, so the traced function only gathers and blends.
Residuals are quantity-aware: positions and velocities subtract, joint angles wrap to
(-pi, pi], orientations use the rotation vector of q_pred^-1 q_meas (not components).
"""
from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from ..errors import DataError
from ..scene import Observation
from .kinds import OBSERVATION_KINDS, ObservationKind, register_kind

# the observation kinds (``kinds.OBSERVATION_KINDS``), by name; the language reads them too
QUANTITIES = OBSERVATION_KINDS


@dataclass(frozen=True)
class Interpolation:
    """Static linear interpolation from the rollout grid onto measurement times."""

    rows: np.ndarray  # (2N,) int32: the grid point at or before each time, then the one after
    w: np.ndarray  # (N,) weight of the one after

    @property
    def lo(self) -> np.ndarray:
        return self.rows[: len(self.w)]

    @property
    def hi(self) -> np.ndarray:
        return self.rows[len(self.w):]


def interpolation(grid: np.ndarray, times: np.ndarray, file: str = "") -> Interpolation:
    """Weights to read values on ``grid`` (uniform, sorted) at ``times``."""
    if len(times) and (times[0] < grid[0] - 1e-9 or times[-1] > grid[-1] + 1e-9):
        raise DataError(f"measurement times [{times[0]:g}, {times[-1]:g}] s fall outside the "
                        f"simulated span [{grid[0]:g}, {grid[-1]:g}] s", file,
                        hint="set world { duration: ... } to cover the data")
    dt = grid[1] - grid[0] if len(grid) > 1 else 1.0
    pos = np.clip((times - grid[0]) / dt, 0, len(grid) - 1)
    lo = np.clip(np.floor(pos).astype(int), 0, len(grid) - 1)
    hi = np.clip(lo + 1, 0, len(grid) - 1)
    w = np.where(hi > lo, pos - lo, 0.0)
    # both neighbours in one int32 array: one gather (XLA indexes by int32; int64 indices, or
    # two arrays joined in the traced function, would each cost a kernel of their own)
    return Interpolation(np.concatenate([lo, hi]).astype(np.int32), w)


def source(obs: Observation, simulator) -> str:
    """The Rollout field that ``obs`` is read from."""
    kind = OBSERVATION_KINDS[obs.quantity]
    if obs.target in getattr(simulator, "marker_names", ()):
        return kind.marker_source
    return kind.source


def model_track(rollout, simulator, obs: Observation):
    """The modelled quantity of ``obs`` over the whole rollout grid: (T, D)."""
    field = source(obs, simulator)
    data = getattr(rollout, field)
    if field.startswith("marker"):
        track = data[:, simulator.marker_names.index(obs.target)]
    elif field.startswith("body"):
        track = data[:, simulator.body_names.index(obs.target)]
    else:
        track = data[:, simulator.joint_names.index(obs.target)][:, None]
    read = OBSERVATION_KINDS[obs.quantity].read
    return track if read is None else read(track)


def predict(rollout, simulator, obs: Observation, interp: Interpolation):
    """Noise-free prediction of ``obs`` at its measurement times: (N, D)."""
    track = model_track(rollout, simulator, obs)
    w = jnp.asarray(interp.w)[:, None]
    n = len(interp.w)
    rows = track[jnp.asarray(interp.rows)]
    out = rows[:n] * (1 - w) + rows[n:] * w
    if OBSERVATION_KINDS[obs.quantity].normalise:
        out = out / jnp.linalg.norm(out, axis=-1, keepdims=True)
    return out


def _quat_conj_mul(p, q):
    """p^-1 (x) q for unit quaternions (w, x, y, z), batched over leading axes."""
    pw, pv = p[..., :1], -p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - jnp.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + jnp.cross(pv, qv)
    return jnp.concatenate([w, v], axis=-1)


def rotation_vector(q):
    """Rotation vector (axis * angle) of unit quaternions; smooth and NaN-free at zero angle."""
    q = jnp.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s2 = jnp.sum(v * v, axis=-1, keepdims=True)
    s = jnp.sqrt(jnp.where(s2 > 1e-24, s2, 1.0))
    angle = 2.0 * jnp.arctan2(s, q[..., :1])
    scale = jnp.where(s2 > 1e-24, angle / s, 2.0 / jnp.maximum(q[..., :1], 1e-12))
    return v * scale


def wrapped(predicted, measured):
    """measured - predicted wrapped to (-pi, pi]: the residual of an angle."""
    diff = measured - predicted
    return jnp.arctan2(jnp.sin(diff), jnp.cos(diff))


def rotation_residual(predicted, measured):
    """The rotation vector of q_pred^-1 q_meas: the residual of an orientation."""
    return rotation_vector(_quat_conj_mul(predicted, measured))


def residual(quantity: str, predicted, measured):
    """measured - predicted in the quantity's own geometry: (N, K)."""
    return OBSERVATION_KINDS[quantity].residual(predicted, measured)


def residual_mask(obs: Observation) -> np.ndarray:
    """(N, K) mask of residual components that were measured (a residual of fewer components
    than the measurement, an orientation's, needs the whole row)."""
    k = len(OBSERVATION_KINDS[obs.quantity].axes)
    if obs.mask.shape[1] != k:
        row = obs.mask.all(axis=1)
        return np.repeat(row[:, None], k, axis=1)
    return obs.mask


def axes(quantity: str) -> tuple[str, ...]:
    return OBSERVATION_KINDS[quantity].axes


for _name, _kind in {
    "position": ObservationKind("body_pos", 3, ("x", "y", "z"), ("x", "y", "z"), "m",
                                marker_source="marker_pos"),
    "orientation": ObservationKind("body_quat", 4, ("rx", "ry", "rz"), ("qw", "qx", "qy", "qz"),
                                   "1", rotation_residual, normalise=True, residual_unit="rad",
                                   fault_candidates=False),
    "velocity": ObservationKind("body_vel", 3, ("vx", "vy", "vz"), ("vx", "vy", "vz"), "m/s",
                                marker_source="marker_vel"),
    "angular_velocity": ObservationKind("body_angvel", 3, ("wx", "wy", "wz"),
                                        ("wx", "wy", "wz"), "rad/s", fault_candidates=False),
    "angle": ObservationKind("joint_pos", 1, ("angle",), ("angle",), "rad", wrapped),
    "angular_rate": ObservationKind("joint_vel", 1, ("rate",), ("rate",), "rad/s"),
}.items():
    register_kind(_name, _kind, __name__)
