"""The posterior container under whichever arviz is installed (0.19-0.23 InferenceData or
>= 1.0 DataTree): built, written, read back, summarised and scored the same way."""
import warnings
from pathlib import Path

import numpy as np
import pytest

from physdsl.infer import posterior_data as pd

DATA = Path(__file__).resolve().parent / "data"


def _posterior(rng):
    post = {"a": rng.normal(2.0, 0.5, (2, 400)),
            "v": rng.normal([1.0, -1.0, 3.0], 0.1, (2, 400, 3))}
    ll = rng.normal(-1.0, 0.2, (2, 400, 12))
    obs = {"obs:x": np.arange(12.0).reshape(6, 2)}
    dims = {"obs:x": ["t", "axis"], "obs:y": ["t2"]}
    return pd.from_dict({"posterior": post, "log_likelihood": {"obs:y": ll},
                         "observed_data": obs, "sample_stats": {}},
                        dims=dims, coords={"axis": ["x", "y"]}), post, ll


def test_round_trip_keeps_groups_values_attributes_and_an_added_group(tmp_path):
    rng = np.random.default_rng(0)
    idata, post, ll = _posterior(rng)
    assert set(pd.group_names(idata)) == {"posterior", "log_likelihood", "observed_data"}
    wide = {k: 2.0 * v for k, v in post.items()}
    pd.add_group(idata, "posterior_robust", wide, {"method": "test", "max_widening": 2.0})
    idata.attrs["intervals"] = "robust"
    path = pd.write(idata, tmp_path / "posterior.nc")
    back = pd.read(path)
    assert set(pd.group_names(back)) == {"posterior", "log_likelihood", "observed_data",
                                         "posterior_robust"}
    assert back.attrs["intervals"] == "robust"
    for name, arr in post.items():
        np.testing.assert_array_equal(pd.group(back, "posterior")[name].values, arr)
        np.testing.assert_array_equal(pd.group(back, "posterior_robust")[name].values, 2 * arr)
    robust = pd.group(back, "posterior_robust")
    assert robust.attrs["method"] == "test" and float(robust.attrs["max_widening"]) == 2.0
    np.testing.assert_array_equal(pd.group(back, "log_likelihood")["obs:y"].values, ll)
    observed = pd.group(back, "observed_data")["obs:x"]
    assert observed.dims == ("t", "axis") and list(observed["axis"].values) == ["x", "y"]
    assert pd.group(back, "sample_stats") is None  # an empty group is left out


def test_summary_statistics_match_numpy_and_detect_disagreeing_chains():
    rng = np.random.default_rng(1)
    idata, post, _ = _posterior(rng)
    x = pd.group(idata, "posterior")["a"].values
    assert float(np.mean(x)) == pytest.approx(np.mean(post["a"]), rel=1e-12)
    assert float(np.quantile(x, 0.95)) == pytest.approx(np.quantile(post["a"], 0.95), rel=1e-12)
    # independent draws: ESS close to the draw count, r-hat close to 1
    assert 600 < pd.ess(x, "bulk") < 1000 and 400 < pd.ess(x, "tail") < 1000
    assert abs(pd.rhat(x) - 1.0) < 0.01
    shifted = x + np.array([[0.0], [3.0]])  # chains centred 3 sd apart
    assert pd.rhat(shifted) > 1.5 and pd.ess(shifted, "bulk") < 50


def test_loo_equals_the_direct_sum_when_importance_weights_are_flat():
    """With a log-likelihood that varies little over draws PSIS is close to the exact LOO
    density, log(1 / mean(1 / p)) per point (the harmonic mean identity); its sum, standard
    error and p_loo are arviz's and checked against that direct computation."""
    rng = np.random.default_rng(2)
    ll = rng.normal(-1.0, 0.05, (2, 500, 8)) + np.linspace(0.0, 1.0, 8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = pd.loo(ll)
    flat = ll.reshape(-1, 8)
    direct = -np.log(np.mean(np.exp(-flat), axis=0))  # exact LOO by importance sampling
    assert r.loo_i.shape == (8,) and r.pareto_k.shape == (8,)
    np.testing.assert_allclose(r.loo_i, direct, atol=1e-3)
    assert r.elpd_loo == pytest.approx(direct.sum(), abs=5e-3)
    assert r.se == pytest.approx(np.sqrt(8 * np.var(r.loo_i)), rel=1e-6)
    lppd = np.log(np.mean(np.exp(flat), axis=0)).sum()
    assert r.p_loo == pytest.approx(lppd - r.elpd_loo, abs=1e-6)
    assert np.all(r.pareto_k < 0.7)


@pytest.mark.parametrize("written_by", ["0.23", "1.3"])
def test_a_file_written_under_either_arviz_reads_back(written_by):
    """posterior.nc files written by arviz 0.23.4 and 1.3.0 (``write``, same layout): every
    group, value, coordinate and attribute reads back under the installed version."""
    from physdsl.infer.intervals import shown_posterior

    back = pd.read(DATA / f"posterior_arviz{written_by}.nc")
    assert set(pd.group_names(back)) == {"posterior", "log_likelihood", "observed_data",
                                         "posterior_robust"}
    np.testing.assert_array_equal(pd.group(back, "posterior")["v"].values,
                                  np.arange(60.0).reshape(2, 10, 3))
    np.testing.assert_array_equal(pd.group(back, "log_likelihood")["obs:y"].values,
                                  -np.arange(140.0).reshape(2, 10, 7) / 100)
    observed = pd.group(back, "observed_data")["obs:y"]
    assert list(observed["obs:y:axis"].values) == ["x", "y"]
    post, shown = shown_posterior(back)
    assert shown == "robust" and float(post.attrs["max_widening"]) == 2.0
    np.testing.assert_array_equal(post["a"].values, 2 * np.arange(20.0).reshape(2, 10))


def test_loo_of_a_point_no_draw_moves_is_its_value():
    """A measurement with the same log-likelihood in every draw: its LOO density is that
    value (Pareto k 0) under both arviz versions (1.x refuses the tail fit, 0.x gave NaN)."""
    rng = np.random.default_rng(3)
    ll = rng.normal(-1.0, 0.05, (2, 300, 5))
    ll[..., 2] = -0.25
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = pd.loo(ll)
        rest = pd.loo(ll[..., [0, 1, 3, 4]])
    assert r.loo_i[2] == -0.25 and r.pareto_k[2] == 0.0
    np.testing.assert_allclose(r.loo_i[[0, 1, 3, 4]], rest.loo_i, rtol=1e-12)
    assert r.elpd_loo == pytest.approx(rest.elpd_loo - 0.25, rel=1e-12)
    assert r.p_loo == pytest.approx(rest.p_loo, rel=1e-9)
