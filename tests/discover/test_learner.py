"""The learned force's trainer: its Gauss-Newton parts (any number of unknowns) are the
inference's own where those exist (at most FORWARD_MODE_MAX unknowns), and its Laplace draws
hold the mode."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl
from physdsl.discover.learn import gn_laplace, learner
from physdsl.infer.base import gauss_newton_fn
from physdsl.infer.problem import model_problem

SCENE = """scene p {
  world { timestep: 10 ms  integrator: rk4 }
  body bob { shape: sphere(radius: 5 cm)  mass: 1 kg  position: (0, 0, -1) m }
  joint hinge: hinge(world -> bob) {
    anchor: (0, 0, 0) m
    axis: (0, 1, 0)
    initial ~ normal(0.8 rad, 0.2 rad)
  }
  effect residual_joint_force on hinge { scale: 2 N*m  span: 1 rad  rate: 3 rad/s  hidden: 2 }
  observe hinge.angle from "data.csv" where joint == "hinge" { noise: 3 mrad }
}
"""


def _model(tmp_path):
    t = np.linspace(0.0, 1.0, 21)
    rows = ["t,joint,angle"] + [f"{a:.3f},hinge,{0.8 * np.cos(3.1 * a):.6f}" for a in t]
    (tmp_path / "data.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "p.phys").write_text(SCENE)
    return physdsl.compile(tmp_path / "p.phys")


@pytest.mark.slow  # three compiles of the rollout's derivatives: 190 s at load 14
def test_learner_is_the_inference_gauss_newton_where_that_exists(tmp_path):
    model = _model(tmp_path)
    problem = model_problem(model)
    assert problem.dim == 10  # 9 weights + the initial angle: within FORWARD_MODE_MAX
    x = jnp.asarray(np.random.default_rng(0).normal(0.0, 0.5, problem.dim))
    ours, theirs = learner(problem)(x), gauss_newton_fn(problem)(x)
    for a, b in zip(ours, theirs):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-10, atol=1e-10)
    g = jax.grad(lambda y: problem.logdensity(y, problem.data))(x)  # and the gradient is right
    np.testing.assert_allclose(np.asarray(ours[1]), np.asarray(g), rtol=1e-8, atol=1e-8)


def test_the_laplace_draws_hold_the_mode_and_spread_as_the_inverse_matrix(tmp_path):
    model = _model(tmp_path)
    problem = model_problem(model)
    mode = np.random.default_rng(1).normal(0.0, 0.3, problem.dim)
    H = np.diag(np.linspace(1.0, 1e4, problem.dim))
    idata = gn_laplace(model, problem, mode, H, chains=2)
    w = np.asarray(idata.posterior["residual_joint_force@hinge.weights"].values)
    np.testing.assert_allclose(w[:, 0], np.broadcast_to(mode[1:], w[:, 0].shape), atol=1e-12)
    sd = np.std(w[:, 1:].reshape(-1, w.shape[-1]), axis=0)  # 126 draws
    np.testing.assert_allclose(sd, 1 / np.sqrt(np.diag(H))[1:], rtol=0.3)
