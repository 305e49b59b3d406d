"""PSIS-LOO over all measurements, and its reliability said in words instead of a raw warning."""
import warnings

import arviz as az
import numpy as np

from physdsl.diagnose.rank import combined_loo, loo_reliability


def _idata(ll):
    return az.from_dict(posterior={"x": np.zeros(ll.shape[:2])}, log_likelihood={"obs:a": ll})


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
