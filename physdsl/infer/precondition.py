"""The Laplace frame: an affine change of variables x = shift + scale z in which the posterior
near its best start is close to a standard normal, for the gradient samplers.

Physical unknowns have posterior widths of millimetres next to metres per second, and are
correlated (a launch point with its velocity). Stan's window adaptation starts from an
identity mass matrix and regularises each estimate toward 1e-3 times the identity, which is
far too wide for such widths: the first windows built trees of up to 63 leapfrog steps where
sampling needed 7 (the README's thrown ball: warmup took 8x the sampling's time per
transition). In the Laplace
frame (``scale`` a square root of the inverse curvature at the start: Gauss-Newton where the
likelihood is least squares, else central differences) unit widths are right from the first
transition. HMC is exact in any affine frame; only its efficiency changes. Where no curvature
is available (a flat direction, a kink), the frame is the identity and nothing changes.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .backends.map import LaplaceError, gauss_newton_sqrt, laplace_sqrt
from .base import value_and_grad_fn


def laplace_frame(problem, positions, lps=None) -> tuple[np.ndarray, np.ndarray]:
    """(shift, scale) of the Laplace frame at the best of ``positions`` by log density (``lps``
    where the caller has them: each costs a rollout): ``scale`` S with S S^T the inverse
    curvature there, or the identity where there is none."""
    positions = np.asarray(positions, dtype=float)
    dim = positions.shape[1]
    if lps is None:
        vg = value_and_grad_fn(problem)
        lps = [float(vg(jnp.asarray(x))[0]) for x in positions]
    lps = np.asarray(lps, dtype=float)
    lps = np.where(np.isfinite(lps), lps, -np.inf)
    centre = positions[int(np.argmax(lps))]
    scale = gauss_newton_sqrt(problem, centre)
    if scale is None:
        try:
            scale = laplace_sqrt(problem, centre)
        except LaplaceError:
            scale = None
    if scale is None or not np.all(np.isfinite(scale)):
        return np.zeros(dim), np.eye(dim)
    return centre, np.asarray(scale, dtype=float)


def to_frame(shift, scale, x):
    """z with x = shift + scale z (rows of ``x`` for a batch)."""
    return jnp.linalg.solve(scale, (jnp.asarray(x) - shift).T).T


def from_frame(shift, scale, z):
    """x = shift + scale z (rows of ``z`` for a batch)."""
    return shift + jnp.asarray(z) @ scale.T
