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
