"""Laplace evidence: exact on a linear-Gaussian scene; posterior model probabilities."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from physdsl.compile import Model
from physdsl.diagnose.evidence import laplace_log_evidence, model_probabilities, quadratic_log_evidence

from .conftest import load_scene, write_csv

# free flight under fixed gravity: the positions are affine in the unknown initial position
# and velocity, both with normal priors, and the noise is normal with a known scale, so the
# marginal likelihood is a Gaussian density in closed form
FLIGHT = """\
scene flight {
  world {
    timestep: 20 ms
    duration: 1 s
    integrator: rk4
  }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position ~ normal((0, 0, 1) m, 10 cm)
    velocity ~ normal((3, 0, 5) m/s, 1 m/s)
    angular_velocity: (0, 0, 0) rad/s
  }
  observe ball.position from "data.csv" where body == "ball" { noise: 5 mm }
}
"""


def test_laplace_evidence_of_a_linear_gaussian_scene_is_the_analytic_marginal_likelihood(tmp_path):
    times = np.linspace(0.0, 1.0, 21)
    write_csv(tmp_path / "data.csv", times, np.zeros((21, 3)), "ball")
    model = Model(load_scene(tmp_path, FLIGHT))
    truth = {"ball.position": np.array([0.05, -0.02, 1.1]), "ball.velocity": np.array([2.7, 0.4, 5.3])}
    clean = np.asarray(model.predict(truth)["ball.position"])
    y = clean + np.random.default_rng(0).normal(0.0, 0.005, clean.shape)
    write_csv(tmp_path / "data.csv", times, y, "ball")
    model = Model(load_scene(tmp_path, FLIGHT))
    y = model.observed[0].obs.values  # as read back from the file (10 digits)

    # y = b + A theta + noise, A and b from the scene's own (affine) predictions
    mu = np.concatenate([[0, 0, 1], [3, 0, 5]]).astype(float)
    prior_sd = np.array([0.1] * 3 + [1.0] * 3)

    def pred(theta):
        return model.predict({"ball.position": theta[:3], "ball.velocity": theta[3:]})[
            "ball.position"].reshape(-1)

    b = np.asarray(pred(jnp.zeros(6)))
    A = np.asarray(jax.jacfwd(pred)(jnp.zeros(6)))
    assert np.allclose(np.asarray(pred(jnp.asarray(mu))), b + A @ mu, atol=1e-9)  # affine
    cov = A @ np.diag(prior_sd**2) @ A.T + 0.005**2 * np.eye(A.shape[0])
    exact = stats.multivariate_normal(b + A @ mu, cov).logpdf(y.reshape(-1))

    got = laplace_log_evidence(model, values=truth)
    assert got == pytest.approx(exact, abs=1e-8)


def test_quadratic_evidence_from_a_point_off_the_mode_and_not_positive_definite():
    H = np.array([[2.0, 0.3], [0.3, 1.0]])
    mode, peak = np.array([0.4, -1.0]), -3.0
    x = mode + np.array([0.1, 0.05])  # log p(x) = peak - 1/2 (x-mode)^T H (x-mode)
    v = peak - 0.5 * (x - mode) @ H @ (x - mode)
    exact = peak + np.log(2 * np.pi) - 0.5 * np.log(np.linalg.det(H))
    assert quadratic_log_evidence(v, -H @ (x - mode), H) == pytest.approx(exact, abs=1e-12)
    assert quadratic_log_evidence(v, np.zeros(2), np.array([[1.0, 0.0], [0.0, -1.0]])) is None


def test_model_probabilities_softmax_equal_prior_odds_and_na():
    p = model_probabilities({"a": 0.0, "b": np.log(3.0), "c": None})
    assert p["a"] == pytest.approx(0.25) and p["b"] == pytest.approx(0.75) and p["c"] is None


def test_evidence_after_a_map_fit_starts_at_the_fits_best_mode(tmp_path, monkeypatch):
    """A MAP fit remembers its modes; the evidence is taken there (no second mode search, which
    on a contact scene stalls at a kink for several rollouts) and equals the closed form."""
    from physdsl import api
    from physdsl.diagnose import evidence
    from physdsl.infer.backends.map import best_known_mode
    from physdsl.infer.problem import model_problem

    times = np.linspace(0.0, 1.0, 21)
    write_csv(tmp_path / "data.csv", times, np.zeros((21, 3)), "ball")
    model = Model(load_scene(tmp_path, FLIGHT))
    truth = {"ball.position": np.array([0.05, -0.02, 1.1]), "ball.velocity": np.array([2.7, 0.4, 5.3])}
    y = np.asarray(model.predict(truth)["ball.position"])
    write_csv(tmp_path / "data.csv", times, y + np.random.default_rng(1).normal(0, 0.005, y.shape),
              "ball")
    model = Model(load_scene(tmp_path, FLIGHT))
    idata = api.infer(model, backend="map", chains=2, samples=16, progress=False)
    problem = model_problem(model)
    mode = best_known_mode(problem)
    assert mode is not None and mode.shape == (problem.dim,)
    searched = evidence.laplace_log_evidence(model, values=point_values(model, problem, mode))

    def no_search(*a, **k):
        raise AssertionError("the fit's mode is known: no search")

    monkeypatch.setattr(evidence, "find_mode", no_search)
    assert evidence.laplace_log_evidence(model, idata) == pytest.approx(searched, abs=1e-6)
    # as a candidate's refit does (``refit_task.measure``): a fit of the first part of the
    # record (the same structure, so the same compiled Problem cache) comes between the fit
    # and its evidence; the fit's modes are still its own, no search
    cut = Model(model.scene, until=0.6)
    api.infer(cut, backend="map", chains=2, samples=16, progress=False)
    assert best_known_mode(model_problem(cut)) is not None
    assert evidence.laplace_log_evidence(model, idata) == pytest.approx(searched, abs=1e-6)


def point_values(model, problem, x) -> dict:
    """Constrained values of the unknowns at flat unconstrained ``x``."""
    sites = problem.to_constrained(jnp.asarray(x), problem.data)
    return {u.name: np.asarray(sites[u.name]) for u in model.unknowns}


def test_best_known_mode_is_the_highest_remembered_on_this_data():
    from types import SimpleNamespace

    from physdsl.infer.backends.map import REMEMBERED_DATASETS, best_known_mode, remember_modes

    problem = SimpleNamespace(cache={}, data=object())
    assert best_known_mode(problem) is None
    remember_modes(problem, [np.array([1.0, 2.0]), np.array([3.0, 4.0]), np.array([5.0, 6.0])],
                   [-10.0, -2.0, -np.inf])
    assert np.array_equal(best_known_mode(problem), [3.0, 4.0])
    other = SimpleNamespace(cache=problem.cache, data=object())  # another dataset's Problem
    assert best_known_mode(other) is None
    # a fit to another dataset of the structure (refine's leave-future-out fit) keeps this
    # dataset's record; the oldest ages out after REMEMBERED_DATASETS datasets
    remember_modes(other, [np.array([7.0, 8.0])], [-1.0])
    assert np.array_equal(best_known_mode(other), [7.0, 8.0])
    assert np.array_equal(best_known_mode(problem), [3.0, 4.0])
    for _ in range(REMEMBERED_DATASETS - 1):
        remember_modes(SimpleNamespace(cache=problem.cache, data=object()), [np.zeros(2)], [0.0])
    assert best_known_mode(problem) is None
    assert np.array_equal(best_known_mode(other), [7.0, 8.0])
