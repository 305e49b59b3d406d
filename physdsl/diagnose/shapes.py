"""How a model fails: is the residual random, and if not, which simple shape explains it.

Shapes are one-regressor least-squares fits of the residual (weighted by the noise): a constant
(offset), the prediction (gain), its time derivative (time delay), time and time squared (trend),
speed and speed squared, time x prediction (amplitude decaying faster/slower) and time x derivative
(phase drift: period mismatch), and the displacement an unmodelled linear or quadratic drag would
cause (the prediction's velocity, or speed x velocity, integrated twice). Their linearisations are exact to first order in the misfit, e.g.
pred(t - tau) = pred(t) - tau * pred'(t). Plus two tests that are not regressions: the oscillation
envelope (measured vs predicted peak amplitudes) and "misfit only after a contact".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import integrate, signal, stats

# Order of preference when two shapes explain the residual equally well: the simplest first.
SHAPES = ("offset", "gain", "delay", "trend_t", "speed", "trend_t2", "speed2", "drag_linear",
          "drag_quadratic", "decay", "phase")

SHAPE_MEANING = {
    "offset": "constant offset (mean residual with small spread)",
    "gain": "gain error (residual proportional to the predicted value)",
    "delay": "time delay (residual proportional to the predicted velocity)",
    "trend_t": "residual growing linearly with time",
    "trend_t2": "residual growing like time squared",
    "speed": "residual proportional to speed",
    "speed2": "residual proportional to speed squared",
    "drag_linear": "displacement a missing force proportional to -velocity would cause",
    "drag_quadratic": "displacement a missing force proportional to -speed x velocity would cause",
    "decay": "oscillation amplitude decaying faster or slower than predicted",
    "phase": "phase drift (period mismatch)",
    "after_contact": "consistent with noise before a contact, off after it",
    "random": "random but larger than the noise scale",
    "noise_overestimated": "residuals much smaller than the noise scale",
}


@dataclass(frozen=True)
class Randomness:
    """Tests of one axis' standardised residuals against independent N(0, 1) noise."""

    n: int
    rms_sigma: float
    mean_sigma: float
    chi2_p: float        # P(sum r^2 at least this large | noise): small = misfit larger than noise
    chi2_p_low: float    # P(sum r^2 at most this small | noise): small = noise overestimated
    runs: int            # Wald-Wolfowitz runs of residual signs
    runs_expected: float
    runs_z: float
    runs_p: float        # one-sided: too few runs = residuals clump in sign = systematic
    lag1: float          # lag-1 autocorrelation (about zero, since the residual should be zero-mean)
    lag1_p: float        # one-sided: positive autocorrelation = systematic


@dataclass(frozen=True)
class ShapeScore:
    """How well one shape explains the residual: r is the cosine between residual and regressor."""

    shape: str
    r: float        # signed (uncentred) correlation of residual and fit, noise-weighted; the sign
                    # is that of coef
    coef: float     # least-squares factor of the shape's regressor: error ~ coef * regressor
                    # (+ companion term for decay and phase), error in the observable's unit
    p_value: float  # F test of the fit against no fit
    ss: float       # sum of squared standardised residuals the shape was fitted to


def randomness(r: np.ndarray) -> Randomness:
    """Chi-square, Wald-Wolfowitz runs and lag-1 autocorrelation tests of the finite entries of r."""
    v = np.asarray(r, dtype=float)
    v = v[np.isfinite(v)]
    n = v.size
    if n < 3:
        nan = float("nan")
        return Randomness(n, float(np.sqrt(np.mean(v * v))) if n else nan,
                          float(np.mean(v)) if n else nan, 1.0, 1.0, n, nan, 0.0, 1.0, 0.0, 1.0)
    ss = float(np.sum(v * v))
    chi2_p = float(stats.chi2.sf(ss, n))
    chi2_p_low = float(stats.chi2.cdf(ss, n))
    runs, expected, z, runs_p = runs_test(v)
    lag1 = float(np.sum(v[1:] * v[:-1]) / ss) if ss > 0 else 0.0
    lag1_p = float(stats.norm.sf(np.sqrt(n) * lag1))
    return Randomness(n, float(np.sqrt(ss / n)), float(np.mean(v)), chi2_p, chi2_p_low, runs,
                      expected, z, runs_p, lag1, lag1_p)


def runs_test(v: np.ndarray) -> tuple[int, float, float, float]:
    """Wald-Wolfowitz runs test on signs: (runs, expected runs, z, one-sided p of too few runs)."""
    s = np.sign(v)
    s = s[s != 0]
    n = s.size
    pos = int(np.count_nonzero(s > 0))
    neg = n - pos
    runs = int(1 + np.count_nonzero(s[1:] != s[:-1])) if n else 0
    if pos == 0 or neg == 0:
        # every residual has the same sign: as unlikely as n fair coins agreeing
        return runs, float("nan"), float("-inf"), float(min(1.0, 2.0 * 0.5 ** n))
    expected = 2.0 * pos * neg / n + 1.0
    var = 2.0 * pos * neg * (2.0 * pos * neg - n) / (n * n * (n - 1.0))
    z = (runs - expected) / np.sqrt(var) if var > 0 else 0.0
    return runs, float(expected), float(z), float(stats.norm.cdf(z))


def oscillates(mean: np.ndarray) -> bool:
    """Whether a prediction swings about its mean at least three times (so envelope/phase apply)."""
    m = np.asarray(mean, dtype=float)
    c = m - np.mean(m)
    scale = np.max(np.abs(c)) if c.size else 0.0
    if scale <= 0:
        return False
    peaks, _ = signal.find_peaks(np.abs(c), prominence=0.3 * scale)
    return peaks.size >= 3


def regressors(times: np.ndarray, mean: np.ndarray, velocity: np.ndarray,
               speed: np.ndarray | None) -> dict[str, np.ndarray]:
    """The candidate misfit shapes as regressors over the given samples (time from the first):
    (n,) for one regressor, (n, 2) for a shape fitted with a companion term (shape last)."""
    t = times - times[0]
    out = {
        "offset": np.ones_like(times),
        "gain": mean,
        "delay": velocity,
        "trend_t": t,
        "trend_t2": t * t,
    }
    if speed is not None:
        out["speed"] = speed
        out["speed2"] = speed * speed
        out["drag_linear"] = double_integral(times, velocity)
        out["drag_quadratic"] = double_integral(times, speed * velocity)
    if oscillates(mean):
        # with the time-independent part alongside, so an amplitude (phase) error that a fit
        # has balanced around mid-record still shows as a decay (drift); the last column is the shape
        swing = mean - np.mean(mean)
        out["decay"] = np.stack([swing, t * swing], axis=1)
        out["phase"] = np.stack([velocity, t * velocity], axis=1)
    return out


def double_integral(times: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Displacement from acceleration ``a`` starting at rest at the first sample (trapezoid rule)."""
    v = integrate.cumulative_trapezoid(a, times, initial=0.0)
    return integrate.cumulative_trapezoid(v, times, initial=0.0)


def shape_scores(times: np.ndarray, error: np.ndarray, noise: np.ndarray, mean: np.ndarray,
                 velocity: np.ndarray, speed: np.ndarray | None) -> list[ShapeScore]:
    """Score every candidate shape on one axis' finite samples, in ``SHAPES`` order."""
    ok = np.isfinite(error)
    if speed is not None:
        ok &= np.isfinite(speed)
    if ok.sum() < 4:
        return []
    sp = None if speed is None else speed[ok]
    regs = regressors(times[ok], mean[ok], velocity[ok], sp)
    w = 1.0 / noise[ok]
    rw = error[ok] * w
    rr = float(rw @ rw)
    n = rw.size
    out = []
    if rr <= 0:
        return []
    for name in SHAPES:
        if name not in regs:
            continue
        x = regs[name].reshape(n, -1) * w[:, None]
        k = x.shape[1]
        if np.sum(x[:, -1] ** 2) <= 1e-300 * max(1.0, rr) or n <= k + 1:
            continue
        coef, *_ = np.linalg.lstsq(x, rw, rcond=None)
        explained = min(float(np.sum((x @ coef) ** 2)), rr)
        cos = np.sign(coef[-1]) * np.sqrt(explained / rr)
        rest = max(rr - explained, 1e-300)
        f = (explained / k) / (rest / (n - k))
        out.append(ShapeScore(name, float(cos), float(coef[-1]),
                              float(stats.f.sf(f, k, n - k)), rr))
    return out


def best_shape(scores: list[ShapeScore], tie: float = 10.0) -> ShapeScore | None:
    """The best-explaining shape; among those whose residual sum of squares (in noise units) is
    within ``tie`` of the best one's, the simplest (earliest in SHAPES)."""
    if not scores:
        return None
    top = max(s.r * s.r for s in scores)
    for name in SHAPES:
        for s in scores:
            if s.shape == name and s.ss * (top - s.r * s.r) <= tie:
                return s
    return None


@dataclass(frozen=True)
class Envelope:
    """Measured vs predicted oscillation amplitude at the predicted peaks."""

    times: np.ndarray   # peak times
    ratio: np.ndarray   # measured amplitude / predicted amplitude at each peak
    rate: float         # slope of log(ratio) in 1/s: < 0 measured decays faster than predicted
    r: float            # correlation of log(ratio) with time
    p_value: float      # of the slope (two-sided)


def envelope(times: np.ndarray, measured: np.ndarray, mean: np.ndarray) -> Envelope | None:
    """Compare the oscillation envelopes of measurement and prediction about the predicted centre.

    At each peak of |prediction - centre| the measured amplitude is the largest (3-sample smoothed)
    measured swing on the same side within a quarter period, so a small phase slip does not hide it.
    """
    ok = np.isfinite(measured)
    t, y, m = times[ok], measured[ok], mean[ok]
    if t.size < 12 or not oscillates(m):
        return None
    c = np.mean(m)
    pc, yc = m - c, y - c
    ys = np.convolve(yc, np.ones(3) / 3.0, mode="same")
    peaks, _ = signal.find_peaks(np.abs(pc), prominence=0.3 * np.max(np.abs(pc)))
    if peaks.size < 3:
        return None
    half = max(1, int(np.median(np.diff(peaks)) // 4))
    amps_p, amps_m = [], []
    for i in peaks:
        side = np.sign(pc[i])
        lo, hi = max(0, i - half), min(t.size, i + half + 1)
        amps_p.append(abs(pc[i]))
        amps_m.append(max(float(np.max(side * ys[lo:hi])), 1e-12 * abs(pc[i])))
    ratio = np.asarray(amps_m) / np.asarray(amps_p)
    fit = stats.linregress(t[peaks], np.log(ratio))
    return Envelope(t[peaks], ratio, float(fit.slope), float(fit.rvalue), float(fit.pvalue))


@dataclass(frozen=True)
class AfterEvent:
    """A misfit that starts at a model contact: noise-like before it, significantly worse after."""

    event: float
    rms_before: float
    rms_after: float
    p_before: float   # chi-square p of the samples before (large = consistent with noise)
    p_value: float    # F test: mean square after vs before


def after_event(times: np.ndarray, r: np.ndarray, events: tuple[float, ...],
                guard: int = 2, alpha: float = 0.01) -> AfterEvent | None:
    """The contact where the misfit starts: the latest event before which the residual is
    noise-like and after which it is not (an earlier event has the misfit in its "after" too).

    ``guard`` samples just before the event are left out, so a contact the model places slightly
    late does not count against "noise-like before".
    """
    ok = np.isfinite(r)
    t, v = times[ok], r[ok]
    for e in sorted(events, reverse=True):
        before = np.flatnonzero(t < e)
        after = v[t >= e]
        before = v[before[: max(0, before.size - guard)]]
        if before.size < 5 or after.size < 5:
            continue
        ms_b, ms_a = float(np.mean(before ** 2)), float(np.mean(after ** 2))
        p_before = float(stats.chi2.sf(ms_b * before.size, before.size))
        runs_p = runs_test(before)[3]
        p = float(stats.f.sf(ms_a / max(ms_b, 1e-300), after.size, before.size))
        if p_before > alpha and runs_p > alpha and p < alpha and ms_a > 2.0 * ms_b:
            return AfterEvent(float(e), float(np.sqrt(ms_b)), float(np.sqrt(ms_a)), p_before, p)
    return None
