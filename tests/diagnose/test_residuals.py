"""Standardised residuals, predictive band, windows and misfit spans on arrays with known answers."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from physdsl.diagnose.residuals import ObservableFit, residuals
from physdsl.diagnose.windows import choose_windows, rms, running_mean, systematic_spans


def fit_of(measured, predicted, noise, mask=None, times=None, speed=None, events=(), point=None):
    n, d = measured.shape
    times = np.arange(n) * 0.01 if times is None else times
    mask = np.ones((n, d), bool) if mask is None else mask
    return ObservableFit("b.p", tuple("xyz"[:d]), "m", times, measured, mask, predicted, noise,
                         speed, events, point)


def test_standardised_residual_is_error_over_mean_noise():
    rng = np.random.default_rng(0)
    measured = rng.normal(size=(5, 2))
    predicted = rng.normal(size=(3, 5, 2))
    noise = np.array([[0.1, 0.2], [0.3, 0.4], [0.2, 0.3]])
    mask = np.ones((5, 2), bool)
    mask[2, 1] = False
    res = residuals(fit_of(measured, predicted, noise, mask))
    expect = (measured - predicted.mean(0)) / noise.mean(0)
    assert np.allclose(res.r[mask], expect[mask])
    assert np.isnan(res.r[2, 1]) and np.isnan(res.measured[2, 1])
    # (S, D) and (S, N, D) noise give the same answer
    full = np.broadcast_to(noise[:, None, :], (3, 5, 2))
    assert np.allclose(residuals(fit_of(measured, predicted, full, mask)).r[mask], res.r[mask])


def drop(t, h0, e=0.8, g=9.81):
    """Height of a ball dropped from rest at h0 that bounces once with restitution e."""
    t_hit = np.sqrt(2 * h0 / g)
    tau = t - t_hit
    return np.where(t < t_hit, h0 - 0.5 * g * t**2, e * g * t_hit * tau - 0.5 * g * tau**2)


def test_residuals_from_the_point_prediction_not_the_mean_of_draws():
    """An approximate posterior with a few wild draws (a Laplace approximation across a bounce
    can have a near-flat direction): the draws' mean is far from every trajectory the model
    gives; the prediction at the fit (one of the good draws) matches the data to the noise."""
    rng = np.random.default_rng(3)
    t = np.linspace(0, 0.8, 161)
    sigma = 0.003
    measured = (drop(t, 0.8) + sigma * rng.standard_normal(t.size))[:, None]
    h0 = np.r_[0.8 + 0.001 * rng.standard_normal(198), 5.0, 9.0]
    predicted = np.stack([drop(t, h) for h in h0])[:, :, None]
    point = drop(t, h0[0])[:, None]
    noise = np.full((h0.size, 1), sigma)
    smeared = residuals(fit_of(measured, predicted, noise, times=t))
    central = residuals(fit_of(measured, predicted, noise, times=t, point=point))
    assert rms(smeared.r) > 10.0
    assert rms(central.r) < 1.3
    assert np.allclose(central.center, point)
    with pytest.raises(ValueError, match="point"):
        residuals(fit_of(measured, predicted, noise, times=t, point=point[1:]))


def test_predictive_band_has_its_coverage_and_includes_parameter_spread():
    rng = np.random.default_rng(1)
    n, sigma, tau = 4000, 0.5, 1.2
    centre = np.zeros((n, 1))
    measured = centre + rng.normal(scale=np.hypot(sigma, tau), size=(n, 1))
    predicted = centre[None] + tau * rng.standard_normal((200, 1, 1))  # parameter uncertainty
    res = residuals(fit_of(measured, predicted, np.full((200, 1), sigma)))
    inside = (measured >= res.band_lo) & (measured <= res.band_hi)
    assert abs(inside.mean() - 0.95) < 0.02
    width = float(np.median(res.band_hi - res.band_lo))
    assert width == pytest.approx(2 * stats.norm.isf(0.025) * np.hypot(sigma, tau), rel=0.08)


def test_wrong_shapes_are_refused():
    m = np.zeros((4, 2))
    with pytest.raises(ValueError, match="predicted"):
        residuals(fit_of(m, np.zeros((3, 4, 3)), np.ones((3, 2))))
    with pytest.raises(ValueError, match="noise_sigma"):
        residuals(fit_of(m, np.zeros((3, 4, 2)), np.ones((2, 2))))
    with pytest.raises(ValueError, match="positive"):
        residuals(fit_of(m, np.zeros((3, 4, 2)), np.zeros((3, 2))))
    with pytest.raises(ValueError, match="sorted"):
        residuals(fit_of(m, np.zeros((3, 4, 2)), np.ones((3, 2)), times=np.array([0, 2, 1, 3.])))


def test_velocity_is_derivative_of_mean_prediction():
    t = np.linspace(0, 1, 101)
    pred = np.sin(3 * t)[None, :, None]
    res = residuals(fit_of(pred[0], pred, np.ones((1, 1)), times=t))
    assert np.allclose(res.velocity[1:-1, 0], 3 * np.cos(3 * t[1:-1]), atol=2e-3)


def test_slices_cover_every_sample_once_and_events_make_segments():
    t = np.linspace(0, 2, 201)
    wins = choose_windows(t, events=(0.5, 0.51, 1.5, 1.999, 5.0), n=4)
    slices = [w for w in wins if w.kind == "slice"]
    counts = np.sum([w.contains(t) for w in slices], axis=0)
    assert len(slices) == 4 and np.all(counts == 1)
    segs = [w for w in wins if w.kind == "segment"]
    # 0.51 is too close to 0.5, 1.999 too close to the end, 5.0 outside: contacts at 0.5 and 1.5
    assert [(w.t_start, w.t_end) for w in segs] == [(0.0, 0.5), (0.5, 1.5), (1.5, 2.0)]
    assert np.all(np.sum([w.contains(t) for w in segs], axis=0) == 1)
    assert segs[0].label.startswith("before") and segs[-1].label.startswith("after")


def test_running_mean_and_rms_skip_missing_values():
    r = np.array([1.0, np.nan, 3.0, 5.0, np.nan])
    assert rms(r) == pytest.approx(np.sqrt(35 / 3))
    sm = running_mean(r, 3)
    assert np.isnan(sm[1]) and sm[2] == pytest.approx(3.0) and sm[0] == pytest.approx(2.0)


def test_systematic_span_found_where_the_offset_is():
    rng = np.random.default_rng(2)
    t = np.linspace(0, 10, 500)
    r = rng.standard_normal(500)
    r[(t > 4) & (t < 6)] += 2.0
    spans = systematic_spans(t, r)
    assert len(spans) >= 1
    s = spans[0]
    assert abs(s.t_start - 4) < 0.4 and abs(s.t_end - 6) < 0.4
    assert s.mean_sigma > 1.5


def test_no_spans_in_pure_noise_mostly():
    hits = sum(bool(systematic_spans(np.arange(300.), np.random.default_rng(s).standard_normal(300)))
               for s in range(100))
    assert hits <= 5
