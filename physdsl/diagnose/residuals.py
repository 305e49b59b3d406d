"""Standardised residuals of measurements against posterior-predictive draws.

An ``ObservableFit`` is what the inference stage hands over for one measured quantity; ``residuals``
turns it into the arrays every later test works on: r = (measured - central prediction) / noise,
with noise the posterior-mean noise scale, and the predictive band from the draws plus noise.

The central prediction is the model's trajectory at its fit, the most likely posterior draw
(``ObservableFit.point``, see ``workflow.point_estimate``), when given, else the mean over
draws. The plug-in is the principled choice for judging a *model*: it is a trajectory the
model can actually produce (the mean of draws that bounce at slightly different times is not:
it smears every bounce), a few wild draws of an approximate posterior cannot move it, and it
is the very point at which ``diagnose`` linearises its score tests. The draws still give the
predictive band.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ObservableFit:
    """One measured observable with its posterior-predictive draws (plain numpy arrays)."""

    name: str                 # e.g. "ball.position", "hinge.angle"
    axes: tuple[str, ...]     # e.g. ("x", "y", "z"), ("angle",)
    unit: str                 # SI unit text of the values, e.g. "m", "rad"
    times: np.ndarray         # (N,) seconds, sorted
    measured: np.ndarray      # (N, D)
    mask: np.ndarray          # (N, D) bool, True where measured
    predicted: np.ndarray     # (S, N, D) posterior draws of the noise-free model prediction
    noise_sigma: np.ndarray   # (S, D) or (S, N, D) posterior draws of the noise scale; broadcastable
    speed: np.ndarray | None  # (N,) model speed of the observed body/joint (at the fit)
    events: tuple[float, ...]  # times of contacts/impacts detected in the model (may be empty)
    point: np.ndarray | None = None  # (N, D) prediction at the fit (the most likely draw)


@dataclass(frozen=True)
class Residuals:
    """Per-sample arrays of one observable; entries where nothing was measured are NaN."""

    name: str
    axes: tuple[str, ...]
    unit: str
    times: np.ndarray      # (N,)
    measured: np.ndarray   # (N, D), NaN where unmeasured
    valid: np.ndarray      # (N, D) bool: measured and finite
    center: np.ndarray     # (N, D) central noise-free prediction (``fit.point``, else draws' mean)
    noise: np.ndarray      # (N, D) posterior mean of the noise scale
    error: np.ndarray      # (N, D) measured - center, in the observable's unit (NaN where invalid)
    r: np.ndarray          # (N, D) standardised residual error / noise (NaN where invalid)
    velocity: np.ndarray   # (N, D) time derivative of the central prediction
    band_lo: np.ndarray    # (N, D) lower edge of the central predictive band (draws + noise)
    band_hi: np.ndarray    # (N, D) upper edge
    band_level: float      # probability mass inside [band_lo, band_hi]
    speed: np.ndarray | None
    events: tuple[float, ...]


def validate(fit: ObservableFit) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Check the shapes of ``fit`` and return (times, measured, mask, predicted, noise) as float arrays.

    ``predicted`` comes back as (S, N, D) and ``noise`` broadcast to (S, N, D). A wrong shape is a
    programming error in the caller, so it raises ValueError naming the field.
    """
    times = np.asarray(fit.times, dtype=float).reshape(-1)
    n = times.size
    d = len(fit.axes)
    measured = np.asarray(fit.measured, dtype=float)
    if measured.ndim == 1 and d == 1:
        measured = measured[:, None]
    if measured.shape != (n, d):
        raise ValueError(f"{fit.name}: measured has shape {measured.shape}, expected {(n, d)}")
    mask = np.asarray(fit.mask, dtype=bool)
    if mask.ndim == 1 and d == 1:
        mask = mask[:, None]
    if mask.shape != (n, d):
        raise ValueError(f"{fit.name}: mask has shape {mask.shape}, expected {(n, d)}")
    if n > 1 and np.any(np.diff(times) < 0):
        raise ValueError(f"{fit.name}: times are not sorted")
    predicted = np.asarray(fit.predicted, dtype=float)
    if predicted.ndim == 2:
        predicted = predicted[None]
    if predicted.ndim != 3 or predicted.shape[1:] != (n, d):
        raise ValueError(f"{fit.name}: predicted has shape {predicted.shape}, expected (S, {n}, {d})")
    s = predicted.shape[0]
    noise = np.asarray(fit.noise_sigma, dtype=float)
    if noise.ndim == 2 and noise.shape == (s, d):
        noise = noise[:, None, :]
    try:
        noise = np.broadcast_to(noise, (s, n, d))
    except ValueError:
        raise ValueError(f"{fit.name}: noise_sigma has shape {np.shape(fit.noise_sigma)}, "
                         f"expected (S, D) or (S, N, D) with S={s}, N={n}, D={d}") from None
    if not np.all(np.isfinite(noise)) or np.any(noise <= 0):
        raise ValueError(f"{fit.name}: noise_sigma must be finite and positive")
    if fit.point is not None and np.shape(fit.point) != (n, d):
        raise ValueError(f"{fit.name}: point has shape {np.shape(fit.point)}, expected {(n, d)}")
    if fit.speed is not None and np.shape(fit.speed) != (n,):
        raise ValueError(f"{fit.name}: speed has shape {np.shape(fit.speed)}, expected ({n},)")
    return times, measured, mask & np.isfinite(measured), predicted, noise


def residuals(fit: ObservableFit, *, band_level: float = 0.95, max_draws: int = 400,
              seed: int = 0) -> Residuals:
    """Standardised residuals and predictive band of one observable (deterministic: fixed seed)."""
    times, measured, valid, predicted, noise = validate(fit)
    center = predicted.mean(axis=0) if fit.point is None else np.asarray(fit.point, dtype=float)
    noise_mean = noise.mean(axis=0)
    error = np.where(valid, measured - center, np.nan)
    r = error / noise_mean
    lo, hi = predictive_band(predicted, noise, band_level, max_draws, seed)
    if times.size > 1:
        velocity = np.gradient(center, times, axis=0)
    else:
        velocity = np.zeros_like(center)
    speed = None if fit.speed is None else np.asarray(fit.speed, dtype=float)
    return Residuals(
        name=fit.name, axes=tuple(fit.axes), unit=fit.unit, times=times,
        measured=np.where(valid, measured, np.nan), valid=valid, center=center, noise=noise_mean,
        error=error, r=r, velocity=velocity, band_lo=lo, band_hi=hi, band_level=band_level,
        speed=speed, events=tuple(sorted(float(e) for e in fit.events)),
    )


def predictive_band(predicted: np.ndarray, noise: np.ndarray, level: float, max_draws: int,
                    seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Central ``level`` band of y = prediction + noise * N(0, 1), by Monte Carlo over the draws.

    Few posterior draws are replicated (each with fresh noise) so the band's edges are stable.
    """
    s = predicted.shape[0]
    reps = max(1, int(np.ceil(max_draws / s)))
    idx = np.repeat(np.arange(s), reps)
    if idx.size > max_draws:
        idx = idx[np.linspace(0, idx.size - 1, max_draws).astype(int)]
    rng = np.random.default_rng(seed)
    draws = predicted[idx] + noise[idx] * rng.standard_normal((idx.size,) + predicted.shape[1:])
    tail = (1.0 - level) / 2.0
    lo, hi = np.quantile(draws, [tail, 1.0 - tail], axis=0)
    return lo, hi
