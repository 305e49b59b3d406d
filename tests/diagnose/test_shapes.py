"""Randomness tests and misfit-shape fits against known answers."""
from __future__ import annotations

import numpy as np
import pytest

from physdsl.diagnose.shapes import (after_event, best_shape, double_integral, envelope,
                                     randomness, runs_test, shape_scores)


def test_runs_test_matches_its_expectation_on_random_signs():
    rng = np.random.default_rng(0)
    runs, expected = [], []
    for _ in range(400):
        v = rng.standard_normal(60)
        r, e, _, _ = runs_test(v)
        runs.append(r)
        expected.append(e)
    assert np.mean(runs) == pytest.approx(np.mean(expected), abs=0.3)


def test_runs_test_detects_clumped_and_accepts_alternating_signs():
    clumped = np.r_[np.ones(20), -np.ones(20), np.ones(20)]
    assert runs_test(clumped)[3] < 1e-6
    alternating = np.tile([1.0, -1.0], 30)
    assert runs_test(alternating)[3] > 0.99
    assert runs_test(np.ones(30))[3] < 1e-8


def test_lag1_autocorrelation_of_ar1_noise():
    rng = np.random.default_rng(1)
    v = np.zeros(2000)
    for i in range(1, 2000):
        v[i] = 0.8 * v[i - 1] + rng.standard_normal() * 0.6
    res = randomness(v)
    assert res.lag1 == pytest.approx(0.8, abs=0.05) and res.lag1_p < 1e-10
    white = randomness(rng.standard_normal(2000))
    assert abs(white.lag1) < 0.07 and white.chi2_p > 0.001


def test_double_integral_of_constant_acceleration_is_exact():
    t = np.linspace(0, 2, 41)
    assert np.allclose(double_integral(t, np.full_like(t, 3.0)), 1.5 * t ** 2)


def test_shape_coefficients_recover_injected_delay_and_gain():
    t = np.linspace(0, 3, 301)
    mean = np.sin(2 * np.pi * t)
    vel = 2 * np.pi * np.cos(2 * np.pi * t)
    noise = np.full_like(t, 1e-3)
    for shape, error, coef in (("delay", -0.004 * vel, -0.004), ("gain", 0.03 * mean, 0.03)):
        scores = shape_scores(t, error, noise, mean, vel, None)
        best = best_shape(scores)
        assert best.shape == shape and best.coef == pytest.approx(coef, rel=1e-6)
        assert abs(best.r) == pytest.approx(1.0)


def test_simplest_shape_wins_a_tie():
    t = np.linspace(0, 1, 50)
    mean = np.full_like(t, 2.0)  # constant prediction: gain and offset are the same regressor
    scores = shape_scores(t, np.full_like(t, 0.1), np.ones_like(t), mean, np.zeros_like(t), None)
    assert best_shape(scores).shape == "offset"


def test_envelope_rate_of_extra_damping():
    t = np.linspace(0, 5, 500)
    pred = 0.3 + np.cos(2 * np.pi * t)
    meas = 0.3 + np.exp(-0.3 * t) * np.cos(2 * np.pi * t)
    env = envelope(t, meas, pred)
    assert env.rate == pytest.approx(-0.3, abs=0.02) and env.r < -0.99
    assert envelope(t, meas, 0.3 + 0.1 * t) is None  # nothing oscillates


def test_after_event_only_when_clean_before():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 1, 200)
    r = rng.standard_normal(200)
    r[t >= 0.5] += 5.0
    hit = after_event(t, r, (0.2, 0.5))
    assert hit is not None and hit.event == 0.5 and hit.rms_before < 1.3
    r[t < 0.5] += 5.0  # off everywhere: not "after a contact"
    assert after_event(t, r, (0.5,)) is None
