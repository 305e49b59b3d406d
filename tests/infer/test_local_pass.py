"""A Laplace fit's posterior pass from an expansion about each mode (``infer.local_pass``):
where it holds it gives the draws' predictions and log-likelihoods that one rollout a draw
gives, from a few rollouts; where it does not (a Gaussian far wider than the curves allow),
it declines and the pass rolls out every draw."""
from __future__ import annotations

import jax
import numpy as np
import pytest

import physdsl
from physdsl.compile import Model, compile as compile_phys
from physdsl.infer import local_pass, output
from physdsl.infer.backends.map import MAP
from physdsl.infer.base import Settings
from physdsl.infer.problem import make_problem

from .conftest import PROJECTILE_TRUTH, projectile_text, simulated_scene

SETTINGS = dict(backend="map", chains=2, warmup=50, samples=100, seed=2, progress=False)
NOISE = 0.5e-3  # m: a precise record (at the conftest's 11 points of 1 cm the drag
# coefficient is loose enough that the pass declines)


@pytest.fixture(scope="module")
def projectile_model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("precise")
    return compile_phys(simulated_scene(folder, projectile_text(NOISE), PROJECTILE_TRUTH,
                                        np.linspace(0.0, 0.5, 101), NOISE, seed=4))


def _pass_counting(monkeypatch) -> list:
    """Count the draws ``output.posterior_pass`` rolls out (it is the every-draw pass)."""
    calls: list[int] = []
    exact = output.posterior_pass

    def counted(model, problem, flat, *a, **k):
        calls.append(len(flat))
        return exact(model, problem, flat, *a, **k)

    monkeypatch.setattr(output, "posterior_pass", counted)
    return calls


def test_the_expansion_gives_every_draws_predictions_and_log_likelihood(projectile_model,
                                                                        monkeypatch):
    calls = _pass_counting(monkeypatch)
    expanded = physdsl.infer(projectile_model, **SETTINGS)
    assert calls == []  # no draw rolled out one by one
    monkeypatch.setattr(local_pass, "CURVE_TOL", -1.0)  # no expansion holds: every draw rolled out
    rolled = physdsl.infer(projectile_model, **SETTINGS)
    assert calls == [SETTINGS["chains"] * SETTINGS["samples"]]
    for name in expanded.posterior.data_vars:  # the same draws
        np.testing.assert_array_equal(expanded.posterior[name].values,
                                      rolled.posterior[name].values)
    pred = "pred:ball.position"
    a, b = (f.posterior_predictive[pred].values for f in (expanded, rolled))
    err = np.abs(a - b)
    assert np.max(err) < local_pass.CHECK_TOL * NOISE
    spread = rolled.posterior_predictive[pred].values.std(axis=(0, 1))
    assert np.max(spread) > 50 * np.max(err)  # the draws' spread is far above the expansion's error
    ll = "obs:ball.position"
    np.testing.assert_allclose(expanded.log_likelihood[ll].values, rolled.log_likelihood[ll].values,
                               atol=0.01)


def test_a_gaussian_wider_than_the_expansion_allows_is_rolled_out(projectile_model):
    problem, positions = make_problem(projectile_model, jax.random.PRNGKey(0), 1,
                                      start={k: v for k, v in PROJECTILE_TRUTH.items()})
    states, params, _ = MAP().warmup(problem, positions, jax.random.PRNGKey(1), Settings(warmup=50))
    means, sqrts = MAP().gaussian(states, params)
    z = np.random.default_rng(0).standard_normal((1, 40, problem.dim))
    for scale, holds in ((1.0, True), (3000.0, False)):
        flat = means[:, None, :] + np.einsum("cij,cnj->cni", scale * sqrts, z)
        out = local_pass.local_pass(projectile_model, problem, flat, means, scale * sqrts)
        assert (out is not None) == holds


def test_a_cut_fits_later_predictions_are_the_rollouts(projectile_model, monkeypatch):
    """A leave-future-out fit masks the later times; they are scored from its predictions
    (``diagnose.lfo``), so the expansion must hold there too."""
    cut = Model(projectile_model.scene, until=0.25)
    calls = _pass_counting(monkeypatch)
    expanded = physdsl.infer(cut, **SETTINGS)
    assert calls == []
    monkeypatch.setattr(local_pass, "CURVE_TOL", -1.0)
    rolled = physdsl.infer(cut, **SETTINGS)
    pred = "pred:ball.position"
    later = np.asarray(expanded.posterior_predictive[pred].coords["ball.position:time"]) > 0.25
    assert later.sum() > 40
    a = expanded.posterior_predictive[pred].values[:, :, later]
    b = rolled.posterior_predictive[pred].values[:, :, later]
    assert np.max(np.abs(a - b)) < local_pass.CHECK_TOL * NOISE
    assert np.max(b.std(axis=(0, 1))) > 50 * np.max(np.abs(a - b))


def _rolled(clearances):
    return [({local_pass.CLEARANCE_SITE: np.asarray(c)}, None) for c in clearances]


def test_draws_stand_clear_of_a_pair_left_out_only_with_room_beyond_their_spread():
    """The clearance (m) at the mode and at +-STEP sds along two directions, then a checked
    draw: the mode's must exceed REACH_MARGIN times its fall at the farthest draw (|z| 3.5)."""
    z = np.array([[3.5, 0.0], [0.5, -1.0]])
    # 0.17 m at the mode, moved by microns across the posterior: clear
    assert local_pass._clear_of_left_out(_rolled([0.17, 0.17002, 0.16998, 0.17001, 0.16999,
                                                  0.17003]), 5, z)
    # a slope of 0.01 m per sd: 3.5 sds out it has fallen 0.035 m of the 0.05 m at the mode
    assert not local_pass._clear_of_left_out(_rolled([0.05, 0.07, 0.03, 0.05, 0.05, 0.02]), 5, z)
    # the same slope with 0.1 m at the mode: twice the fall fits
    assert local_pass._clear_of_left_out(_rolled([0.1, 0.12, 0.08, 0.1, 0.1, 0.07]), 5, z)
    # a curve that the points either side see: 0.01 m per sd^2, 0.12 m at 3.5 sds
    assert not local_pass._clear_of_left_out(_rolled([0.1, 0.14, 0.14, 0.1, 0.1, 0.2]), 5, z)
    # one point within reach, or not finite: not clear whatever the mode's room
    assert not local_pass._clear_of_left_out(_rolled([1.0, 1.0, 1.0, 1.0, 1.0, -1e-6]), 5, z)
    assert not local_pass._clear_of_left_out(_rolled([1.0, np.nan, 1.0, 1.0, 1.0, 1.0]), 5, z)
