"""Starts for oscillating data: prior draws screened by the frequency they oscillate at.

Where a measured track oscillates over several cycles (a spring, a pendulum), the log
density is periodic-like in whatever sets the frequency: a start whose frequency is off by
more than about one cycle over the record lies in a basin whose prediction runs out of
phase with the data, and Levenberg-Marquardt stays there (spring-mass fits at 2.2σ with the
stiffness 4-8x the truth). The data's dominant frequency is read off their periodogram
(detrended, Hann-windowed); a batch of prior draws, their initial-state unknowns taken from
the start from the data, is simulated in one call of the posterior pass (``output``'s
compiled function, which the run needs anyway for its predictions), and the draws whose
predicted tracks oscillate at the data's frequencies (within one frequency bin, 1/record)
are kept as starts, the best by log density first. Nothing is known about which unknown sets
the frequency: the screen needs only the predictions.
"""
from __future__ import annotations

import numpy as np

from ..compile import PRED_PREFIX
from .data_starts import initial_state_unknowns
from .output import PASS_CHUNK, posterior_pass
from .problem import prior_draws_unconstrained, unconstrained_layout

MIN_CYCLES = 2.0  # fewer cycles of the peak in the record: not an oscillation worth screening
PEAK_SHARE = 0.4  # share of the detrended variance the peak's band must hold
PAD = 8  # zero-padding factor of the periodogram (the peak read to 1/8 of a bin)
QUANTITIES = ("position", "angle", "velocity", "angular_rate")  # plain-difference tracks
SCREEN_DRAWS = PASS_CHUNK  # prior draws simulated for the screen (one call of the pass)
MATCH_BINS = 1.0  # a predicted peak within this many bins (1/record) of the data's matches


def dominant_frequency(times, values) -> tuple[float, float, float]:
    """(frequency in Hz, share of the detrended variance in its band, record length in s) of
    one measured component; frequency 0 where there is no clear peak with ``MIN_CYCLES``."""
    t, y = np.asarray(times, dtype=float), np.asarray(values, dtype=float)
    ok = np.isfinite(t) & np.isfinite(y)
    t, y = t[ok], y[ok]
    if t.size < 16 or t[-1] <= t[0]:
        return 0.0, 0.0, 0.0
    span = float(t[-1] - t[0])
    grid = np.linspace(t[0], t[-1], t.size)
    u = np.interp(grid, t, y)
    s = (grid - grid[0]) / span
    u = u - np.polyval(np.polyfit(s, u, 2), s)  # offsets and slow drifts are not cycles
    total = float(np.sum(u**2))
    if total <= 0.0:
        return 0.0, 0.0, span
    n = u.size * PAD
    power = np.abs(np.fft.rfft(u * np.hanning(u.size), n)) ** 2
    freqs = np.fft.rfftfreq(n, d=span / (u.size - 1))
    # the strongest component above half a cycle: a drift the polynomial left (a smooth
    # curve, its power falling from the lowest frequencies) peaks below MIN_CYCLES
    k = int(np.argmax(np.where(freqs >= 0.5 / span, power, -1.0)))
    band = np.abs(freqs - freqs[k]) <= 2.0 / span  # the Hann window's main lobe
    share = float(np.sum(power[band]) / np.sum(power))
    cycles = freqs[k] * span >= MIN_CYCLES
    return (float(freqs[k]) if share >= PEAK_SHARE and cycles else 0.0), share, span


def oscillations(model) -> list[tuple[str, int, float, float]]:
    """(observation name, component, frequency Hz, record s) of every measured component that
    oscillates over at least ``MIN_CYCLES`` cycles with one dominant frequency."""
    out = []
    for o in model.observed:
        obs = o.obs
        if obs.quantity not in QUANTITIES:
            continue
        values = np.asarray(obs.values, dtype=float).reshape(len(obs.times), -1)
        mask = np.asarray(obs.mask, dtype=bool).reshape(len(obs.times), -1)
        for c in range(values.shape[1]):
            rows = mask[:, c]
            f, _, span = dominant_frequency(np.asarray(obs.times)[rows], values[rows, c])
            if f > 0.0:
                out.append((obs.name, c, f, span))
    return out


def screened_starts(problem, key, from_data, n: int) -> list[np.ndarray]:
    """Up to ``n`` prior draws (flat, unconstrained) whose predictions oscillate at the data's
    dominant frequencies, best log density first; [] where the data do not oscillate or no
    draw matches. ``from_data``: the start from the data, whose initial-state coordinates
    every draw takes (None: the draws as they are)."""
    model = problem.model
    tracks = oscillations(model)
    if not tracks or n <= 0:
        return []
    draws = np.array(prior_draws_unconstrained(problem, key, SCREEN_DRAWS))
    if from_data is not None:
        cols = _initial_state_columns(model)
        draws[:, cols] = np.asarray(from_data, dtype=float)[cols]
    sites, loglik = posterior_pass(model, problem, draws)
    lls = np.sum([np.sum(np.asarray(v).reshape(len(draws), -1), axis=1)
                  for v in loglik.values()], axis=0)
    misses = np.zeros(len(draws))
    by_name = {o.obs.name: o.obs for o in model.observed}
    for name, c, f, span in tracks:
        obs = by_name[name]
        pred = np.asarray(sites[PRED_PREFIX + name]).reshape(len(draws), len(obs.times), -1)
        rows = np.asarray(obs.mask, dtype=bool).reshape(len(obs.times), -1)[:, c]
        for i in range(len(draws)):
            fp, _, _ = dominant_frequency(np.asarray(obs.times)[rows], pred[i, rows, c])
            misses[i] += abs(fp - f) * span > MATCH_BINS
    good = [i for i in np.lexsort((-lls, misses)) if misses[i] == 0 and np.isfinite(lls[i])]
    return [draws[i] for i in good[:n]]


def _initial_state_columns(model) -> np.ndarray:
    """Flat unconstrained coordinates of the unknowns the state at t = 0 depends on."""
    names = initial_state_unknowns(model.scene)
    layout = unconstrained_layout(model)
    sizes = {k: int(np.prod(v.shape)) for k, v in layout.items()}
    cols, at = [], 0
    for k in sorted(layout):  # ravel_pytree's order: the names sorted
        if k in names:
            cols.extend(range(at, at + sizes[k]))
        at += sizes[k]
    return np.asarray(cols, dtype=int)


__all__ = ["dominant_frequency", "oscillations", "screened_starts"]
