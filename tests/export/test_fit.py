"""Fitting posterior draws for export: supports, correlation blocks, widening (numpy only)."""
from __future__ import annotations

import numpy as np
import pytest
from numpyro.distributions import constraints as c

from physdsl.export import Support, classify_constraint, draw_from_fit, fit_draws, prior_support
from physdsl.expr import Const
from physdsl.scene import Prior, Unknown

POS = Support("lower", np.asarray(0.0))
REAL = Support("real")
UNIT = Support("interval", np.asarray(0.0), np.asarray(1.0))


def _correlated_draws(n=20000, seed=0):
    """Draws of three unknowns whose unconstrained values are a known correlated normal."""
    rng = np.random.default_rng(seed)
    mean = np.array([np.log(0.6), 0.7, 0.0])
    sd = np.array([0.05, 0.1, 0.4])
    corr = np.array([[1.0, -0.8, 0.3], [-0.8, 1.0, 0.0], [0.3, 0.0, 1.0]])
    cov = corr * np.outer(sd, sd)
    y = rng.multivariate_normal(mean, cov, n)
    draws = {"L": np.exp(y[:, 0]), "hinge.initial": y[:, 1], "friction": 1 / (1 + np.exp(-y[:, 2]))}
    return draws, mean, cov


def test_classify_constraints():
    assert classify_constraint(c.real, ()).kind == "real"
    s = classify_constraint(c.positive, ())
    assert s.kind == "lower" and s.low == 0
    s = classify_constraint(c.interval(1.0, 3.0), (2,))
    assert s.kind == "interval" and s.low.tolist() == [1.0, 1.0] and s.high.tolist() == [3.0, 3.0]
    assert classify_constraint(c.less_than(2.0), ()).kind == "upper"
    assert classify_constraint(c.independent(c.real, 1), (3,)).kind == "real"
    assert classify_constraint(c.integer_interval(0, 3), ()).kind == "discrete"


def test_prior_support_from_scene_prior():
    half = Unknown("b", Prior("half_normal", (Const(0.01),)), (), "kg/s")
    assert prior_support(half, {}).kind == "lower"
    tn = Unknown("mu", Prior("truncated_normal", (Const(0.5), Const(0.2)),
                             (("low", Const(0.0)), ("high", Const(1.0)))), (), "1")
    s = prior_support(tn, {})
    assert s.kind == "interval" and float(s.high) == 1.0
    vel = Unknown("ball.velocity", Prior("normal", (Const((0.0, 0.0, 0.0)), Const(1.0))), (3,), "m/s")
    assert prior_support(vel, {}).kind == "real"


@pytest.mark.parametrize("support", [POS, REAL, UNIT, Support("interval", np.asarray(-2.0), np.asarray(5.0)),
                                     Support("upper", high=np.asarray(3.0))])
def test_bijection_round_trip(support):
    y = np.linspace(-5, 5, 11)
    x = support.from_unconstrained(y)
    np.testing.assert_allclose(support.to_unconstrained(x), y, rtol=1e-9, atol=1e-9)


def test_correlated_block_recovers_mean_and_covariance():
    draws, mean, cov = _correlated_draws()
    fit = fit_draws(draws, {"L": POS, "hinge.initial": REAL, "friction": UNIT})
    assert len(fit.blocks) == 1 and not fit.marginals
    block = fit.blocks[0]
    assert [n for n, _ in block.components] == ["L", "hinge.initial", "friction"]
    se = np.sqrt(np.diag(cov) / 20000)
    assert np.all(np.abs(block.mean - mean) < 4 * se)
    np.testing.assert_allclose(block.chol @ block.chol.T, cov, atol=0.02 * cov.max())


def test_draws_from_fit_match_posterior_moments():
    draws, _, _ = _correlated_draws()
    fit = fit_draws(draws, {"L": POS, "hinge.initial": REAL, "friction": UNIT})
    new = draw_from_fit(fit, 20000, seed=1)
    a = np.stack([draws[k] for k in draws], 1)
    b = np.stack([new[k] for k in draws], 1)
    sd = a.std(0)
    assert np.all(np.abs(a.mean(0) - b.mean(0)) < 5 * sd / np.sqrt(20000) * np.sqrt(2))
    np.testing.assert_allclose(b.std(0), sd, rtol=0.04)
    np.testing.assert_allclose(np.corrcoef(b.T), np.corrcoef(a.T), atol=0.03)


def test_independent_marginals_match_their_families():
    rng = np.random.default_rng(3)
    n = 20000
    draws = {
        "mass": np.exp(rng.normal(np.log(0.3), 0.02, n)),
        "x": rng.normal([1.0, 2.0, 3.0], [0.1, 0.2, 0.3], (n, 3)),
        "mu": rng.beta(20.0, 30.0, n),
        "e": np.clip(rng.normal(0.9, 0.05, n), 0.0, 0.999),
        "k": rng.choice(3, n, p=[0.2, 0.5, 0.3]),
    }
    supports = {"mass": POS, "x": REAL, "mu": UNIT, "k": Support("discrete"),
                "e": Support("interval", np.asarray(-0.5), np.asarray(1.0))}  # not (0, 1): truncated
    fit = fit_draws(draws, supports)
    assert not fit.blocks
    by = {m.name: m for m in fit.marginals}
    assert by["mass"].dist == "log_normal"
    np.testing.assert_allclose(by["mass"].args["loc"], np.log(0.3), atol=1e-3)
    np.testing.assert_allclose(by["mass"].args["scale"], 0.02, rtol=0.03)
    assert by["x"].dist == "normal" and by["x"].args["loc"].shape == (3,)
    np.testing.assert_allclose(by["x"].args["scale"], [0.1, 0.2, 0.3], rtol=0.03)
    assert by["mu"].dist == "beta"
    np.testing.assert_allclose([by["mu"].args["concentration1"], by["mu"].args["concentration0"]],
                               [[20.0], [30.0]], rtol=0.06)
    assert by["e"].dist == "truncated_normal" and by["e"].args["high"].tolist() == [1.0]
    np.testing.assert_allclose(by["e"].args["loc"], 0.9, atol=0.005)
    assert by["k"].dist == "categorical"
    np.testing.assert_allclose(by["k"].args["probs"], [0.2, 0.5, 0.3], atol=0.015)


def test_support_respected_in_10000_draws():
    rng = np.random.default_rng(5)
    n = 4000
    # masses close to zero and a friction coefficient close to its bound 1, correlated
    y = rng.multivariate_normal([np.log(0.01), 2.5], [[1.0, 0.5], [0.5, 1.0]], n)
    draws = {"mass": np.exp(y[:, 0]), "friction": 1 / (1 + np.exp(-y[:, 1]))}
    for thr in (0.1, 1.1):  # a joint block, then forced independent marginals
        fit = fit_draws(draws, {"mass": POS, "friction": UNIT}, widen=3.0, threshold=thr)
        new = draw_from_fit(fit, 10000, seed=2)
        assert np.all(new["mass"] > 0)
        assert np.all((new["friction"] >= 0) & (new["friction"] <= 1))


def test_widen_scales_unconstrained_sd():
    draws, mean, cov = _correlated_draws()
    sup = {"L": POS, "hinge.initial": REAL, "friction": UNIT}
    f1 = fit_draws(draws, sup)
    f2 = fit_draws(draws, sup, widen=2.0)
    np.testing.assert_allclose(f2.blocks[0].chol, 2.0 * f1.blocks[0].chol, rtol=1e-12)
    np.testing.assert_allclose(f2.blocks[0].mean, f1.blocks[0].mean)


def test_small_correlations_are_written_independently():
    rng = np.random.default_rng(7)
    y = rng.multivariate_normal([0, 0], [[1, 0.02], [0.02, 1]], 5000)
    fit = fit_draws({"a": y[:, 0], "b": y[:, 1]}, {"a": REAL, "b": REAL})
    assert not fit.blocks and [m.dist for m in fit.marginals] == ["normal", "normal"]
