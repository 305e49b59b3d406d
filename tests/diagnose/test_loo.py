"""PSIS-LOO over all measurements, and its reliability said in words instead of a raw warning."""
import warnings

import numpy as np
import pytest

from physdsl.diagnose.loo import combined_loo, loo_reliability, unreliable
from physdsl.infer import posterior_data


def _idata(ll):
    return posterior_data.from_dict({"posterior": {"x": np.zeros(ll.shape[:2])},
                                     "log_likelihood": {"obs:a": ll}})


def test_loo_is_quiet_and_says_when_it_is_unreliable():
    rng = np.random.default_rng(0)
    calm = rng.normal(-1.0, 0.1, (2, 200, 30))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no raw arviz warning reaches the user
        good = combined_loo(_idata(calm))
        wild = calm.copy()
        wild[..., 3] = -rng.pareto(0.3, (2, 200)) * 50  # one point's draws: very heavy tail
        bad = combined_loo(_idata(wild))
    assert abs(good.elpd_loo + 30.0) < 0.5  # 30 measurements at log density -1 +- 0.1
    assert loo_reliability(good) is None
    assert "1 of 30 measurements" in loo_reliability(bad)
    assert not unreliable(good) and not unreliable(bad)  # one bad point of 30: still evidence


def test_loo_of_draws_wider_than_the_posterior_is_not_evidence():
    """Draws from an approximation wider than the posterior (a Laplace Gaussian in log space
    around a strength near zero) put a few draws far off at every point: LOO's harmonic mean
    sinks whatever the fit's quality, and ``unreliable`` says so."""
    rng = np.random.default_rng(2)
    ll = rng.normal(-1.0, 0.05, (2, 200, 40))
    off = rng.random((2, 200)) < 0.05  # one draw in twenty far out in the banana's tail
    ll[off] -= rng.exponential(30.0, (int(off.sum()), 40))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loo = combined_loo(_idata(ll))
    assert loo.elpd_loo < -40.0 * 1.5  # far below the -40 of the draws near the mode
    assert unreliable(loo)


def test_points_no_unknown_moves_have_their_exact_loo_density():
    """A measurement whose log-likelihood is the same in every draw (a block that does not
    rotate: its orientation depends on no unknown) has LOO density equal to that value; PSIS
    alone returns NaN there and made the whole ELPD NaN."""
    rng = np.random.default_rng(1)
    ll = rng.normal(-1.0, 0.1, (2, 100, 10))
    ll[..., 4] = 2.5 + 1e-14 * rng.normal(size=(2, 100))  # constant up to rounding
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loo = combined_loo(_idata(ll))
    assert np.asarray(loo.loo_i)[4] == np.float64(ll[..., 4].mean())
    assert np.isfinite(loo.elpd_loo) and np.isfinite(loo.se) and np.isfinite(loo.p_loo)
    varying = combined_loo(_idata(ll[..., [0, 1, 2, 3, 5, 6, 7, 8, 9]]))
    assert float(loo.elpd_loo) == pytest.approx(float(np.sum(varying.loo_i)) + ll[..., 4].mean(),
                                                rel=1e-12)
    assert np.asarray(loo.pareto_k)[4] == 0.0
