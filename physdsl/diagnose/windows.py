"""Where a model fails in time: automatic windows (equal slices, segments between contacts) and
contiguous spans where the smoothed standardised residual is systematically away from zero."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Window:
    """A time window [t_start, t_end) (the last one closed) over which RMS residuals are reported."""

    label: str
    kind: str        # "slice" (equal span) or "segment" (between model contacts/impacts)
    t_start: float
    t_end: float
    closed: bool = False  # include t_end (true for the window that ends at the last sample)

    def contains(self, times: np.ndarray) -> np.ndarray:
        """Bool mask of the samples inside this window."""
        upper = times <= self.t_end if self.closed else times < self.t_end
        return (times >= self.t_start) & upper


@dataclass(frozen=True)
class MisfitSpan:
    """A contiguous time span whose smoothed residual exceeds what noise alone would give."""

    t_start: float
    t_end: float
    n: int             # measured samples inside
    rms_sigma: float   # RMS of the standardised residual inside
    mean_sigma: float  # mean standardised residual inside (sign: + measurement above model)
    peak_sigma: float  # largest |smoothed residual| inside


def choose_windows(times: np.ndarray, events: tuple[float, ...] = (), n: int = 4,
                   min_points: int = 3) -> list[Window]:
    """``n`` equal slices of the time range, plus the segments between events when there are any."""
    times = np.asarray(times, dtype=float)
    if times.size == 0:
        return []
    t0, t1 = float(times[0]), float(times[-1])
    out: list[Window] = []
    if t1 > t0 and n >= 1:
        edges = np.linspace(t0, t1, n + 1)
        for i in range(n):
            out.append(Window(f"{edges[i]:.3g}-{edges[i + 1]:.3g} s", "slice", float(edges[i]),
                              float(edges[i + 1]), closed=i == n - 1))
    else:
        out.append(Window(f"{t0:.3g}-{t1:.3g} s", "slice", t0, t1, closed=True))
    cuts = usable_events(times, events, min_points)
    if cuts:
        bounds = [t0, *cuts, t1]
        for i in range(len(bounds) - 1):
            a, b = bounds[i], bounds[i + 1]
            if i == 0:
                label = f"before contact at {b:.3g} s"
            elif i == len(bounds) - 2:
                label = f"after contact at {a:.3g} s"
            else:
                label = f"between contacts {a:.3g}-{b:.3g} s"
            out.append(Window(label, "segment", float(a), float(b), closed=i == len(bounds) - 2))
    return out


def usable_events(times: np.ndarray, events: tuple[float, ...], min_points: int = 3) -> list[float]:
    """Events inside the time range that leave at least ``min_points`` samples on each side."""
    cuts: list[float] = []
    last = float(times[0])
    for e in sorted(float(e) for e in events):
        if not (times[0] < e < times[-1]):
            continue
        if np.count_nonzero((times >= last) & (times < e)) < min_points:
            continue
        if np.count_nonzero(times >= e) < min_points:
            continue
        cuts.append(e)
        last = e
    return cuts


def rms(values: np.ndarray) -> float:
    """Root mean square of the finite entries (NaN when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")


def smoothing_width(n: int) -> int:
    """Samples averaged by the running residual: about 1/20 of the record, between 3 and 50."""
    return int(np.clip(round(n / 20), 3, 50))


def running_sums(v: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Centred running (sum, count) of a finite 1-D array over ``k`` neighbours (fewer at the ends)."""
    kernel = np.ones(min(k, v.size))
    return np.convolve(v, kernel, mode="same"), np.convolve(np.ones(v.size), kernel, mode="same")


def running_mean(r: np.ndarray, k: int) -> np.ndarray:
    """Centred running mean of the finite entries of ``r`` over ``k`` neighbours (NaN stays NaN)."""
    r = np.asarray(r, dtype=float)
    ok = np.isfinite(r)
    out = np.full(r.shape, np.nan)
    if ok.any():
        total, count = running_sums(r[ok], k)
        out[ok] = total / count
    return out


def span_threshold(n: int, k: int, alpha: float = 0.01) -> float:
    """z above which a running sum of k residuals is called systematic: two-sided at level
    ``alpha``, Bonferroni-corrected over the n window positions (2n/k had undercounted the
    overlapping windows: on pure noise 3-6x the nominal rate at n = 91-1000; with n it is at or
    below it)."""
    tests = max(1.0, float(n))
    return float(stats.norm.isf(alpha / 2.0 / tests))


def systematic_spans(times: np.ndarray, r: np.ndarray, alpha: float = 0.01) -> list[MisfitSpan]:
    """Contiguous spans where the running residual of one axis is systematically off zero.

    Spans closer than one smoothing width are merged; returned sorted by squared misfit, largest
    first, so the first span is where the model fails most.
    """
    ok = np.isfinite(r)
    n = int(ok.sum())
    if n < 6:
        return []
    k = smoothing_width(n)
    t = np.asarray(times, dtype=float)[ok]
    rv = np.asarray(r, dtype=float)[ok]
    total, count = running_sums(rv, k)
    smooth = total / count
    hot = np.abs(total / np.sqrt(count)) > span_threshold(n, k, alpha)
    runs: list[list[int]] = []
    for i in np.flatnonzero(hot):
        if runs and i - runs[-1][1] <= k:
            runs[-1][1] = i
        else:
            runs.append([i, i])
    spans = []
    for a, b in runs:
        seg = rv[a:b + 1]
        spans.append(MisfitSpan(float(t[a]), float(t[b]), int(seg.size), rms(seg),
                                float(np.mean(seg)), float(np.max(np.abs(smooth[a:b + 1])))))
    spans.sort(key=lambda s: -(s.rms_sigma ** 2) * s.n)
    return spans
