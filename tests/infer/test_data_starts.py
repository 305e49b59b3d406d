"""Starts from the data: initial-state unknowns from a polynomial fit to the first samples."""
from pathlib import Path

import jax
import numpy as np
import pytest

from physdsl.infer.data_starts import (MIN_SAMPLES, _estimate, data_start, initial_state_unknowns,
                                       track_estimates)
from physdsl.infer.problem import make_problem
from physdsl.scene import Noise, Observation
from physdsl.expr import Const

from .conftest import simulated_scene

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

# a throw given as speed and launch angle (not a velocity vector); the drag is no initial state
THROW = """\
scene throw {
  world { timestep: 5 ms  duration: 1 s  integrator: rk4 }
  param speed ~ normal(4 m/s, 1 m/s)
  param angle ~ uniform(10 deg, 80 deg)
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position ~ normal((0, 0, 1) m, 20 cm)
    velocity: (speed * cos(angle), 0 m/s, speed * sin(angle))
  }
  effect linear_drag on ball { coefficient ~ half_normal(0.5 kg/s) }
  observe ball.position from "data.csv" where body == "ball" { noise: 3 mm }
}
"""
THROW_TRUTH = {"speed": 4.6, "angle": np.radians(55.0), "ball.position": np.array([0.05, -0.02, 1.1]),
               "linear_drag@ball.coefficient": 0.05}


def _obs(times, values, quantity="position", noise=0.002):
    values = np.asarray(values, dtype=float)
    return Observation("o", "ball", quantity, Path("x.csv"), np.asarray(times), values,
                       np.ones(values.shape, bool), ("x",), Noise("normal", Const(noise)))


def test_value_and_slope_of_a_noisy_throw_within_their_standard_errors():
    t = np.arange(0, 1.0, 0.01)
    p0, v0, g = np.array([0.1, 0.0, 1.0]), np.array([3.0, 0.5, 4.0]), np.array([0, 0, -9.81])
    clean = p0 + v0 * t[:, None] + 0.5 * g * t[:, None] ** 2
    noisy = clean + np.random.default_rng(1).normal(0, 0.002, clean.shape)
    est = _estimate(_obs(t, noisy))
    assert est.samples == 20  # the first 0.2 s, at most 20 samples
    assert np.all(np.abs(est.value - p0) < 4 * est.value_sd)
    assert np.all(np.abs(est.slope - v0) < 4 * est.slope_sd)
    assert np.all(est.slope_sd < 0.2) and np.all(est.value_sd < 0.002)


def test_angles_are_unwrapped_before_the_fit():
    """A hinge spinning through +-pi: the measured angle jumps by 2 pi; the slope must not."""
    t = np.arange(0, 0.3, 0.01)
    angle = 3.0 + 5.0 * t  # passes pi at t = 0.03 s
    wrapped = np.arctan2(np.sin(angle), np.cos(angle))[:, None]
    est = _estimate(_obs(t, wrapped, "angle", noise=1e-3))
    np.testing.assert_allclose(est.value, [3.0], atol=5e-3)
    np.testing.assert_allclose(est.slope, [5.0], atol=0.1)


def test_a_window_holding_an_impact_is_shortened_until_the_polynomial_fits():
    """A ball dropped 3 cm bounces at t ~ 0.078 s: the 20-sample window misfits, its half does not."""
    t = np.arange(0, 0.4, 0.01)
    h0 = 0.03
    tb = np.sqrt(2 * h0 / 9.81)
    z = np.where(t < tb, h0 - 0.5 * 9.81 * t**2, 9.81 * tb * (t - tb) - 0.5 * 9.81 * (t - tb) ** 2)
    track = np.stack([np.zeros_like(t), np.zeros_like(t), z], axis=1)
    track = track + np.random.default_rng(0).normal(0, 2e-4, track.shape)
    est = _estimate(_obs(t, track, noise=2e-4))
    assert MIN_SAMPLES <= est.samples <= 10
    np.testing.assert_allclose(est.value[2], h0, atol=1e-3)
    np.testing.assert_allclose(est.slope[2], 0.0, atol=0.1)


def test_speed_and_angle_solved_through_the_scene_expressions(tmp_path):
    scene = simulated_scene(tmp_path, THROW, THROW_TRUTH, np.arange(0, 1.0001, 0.01), 0.003, seed=5)
    from physdsl.compile import compile as compile_phys

    model = compile_phys(scene)
    assert initial_state_unknowns(model.scene) == {"speed", "angle", "ball.position"}
    problem, x = make_problem(model, jax.random.PRNGKey(0), 1)
    start = data_start(problem, x[0])
    values = problem.to_constrained(start, problem.data)
    assert abs(float(values["speed"]) - THROW_TRUTH["speed"]) < 0.1  # the prior: 4 +- 1
    assert abs(float(values["angle"]) - THROW_TRUTH["angle"]) < np.radians(1.5)
    np.testing.assert_allclose(values["ball.position"], THROW_TRUTH["ball.position"], atol=0.004)
    # an unknown the initial state does not depend on keeps the given start's value
    before = problem.to_constrained(x[0], problem.data)
    np.testing.assert_allclose(values["linear_drag@ball.coefficient"],
                               before["linear_drag@ball.coefficient"], rtol=1e-12)


def test_a_start_the_data_put_outside_the_prior_lies_in_its_support(tmp_path):
    """The true angle (55 deg) outside a uniform(10, 40 deg) prior: the start stays inside."""
    text = THROW.replace("uniform(10 deg, 80 deg)", "uniform(10 deg, 40 deg)")
    scene = simulated_scene(tmp_path, text, THROW_TRUTH, np.arange(0, 1.0001, 0.01), 0.003, seed=6)
    from physdsl.compile import compile as compile_phys

    problem, x = make_problem(compile_phys(scene), jax.random.PRNGKey(1), 1)
    angle = float(problem.to_constrained(data_start(problem, x[0]), problem.data)["angle"])
    assert np.radians(10) < angle < np.radians(40)
    assert angle > np.radians(35)  # pushed against the edge the data point to


@pytest.mark.slow  # ~19 s; data starts: the other tests here
def test_a_hinge_scene_starts_at_the_encoder_and_track():
    """The pendulum example: release angle and length from the first samples of the bob's
    track and the encoder (truth 40 deg, 0.6 m; priors 40 +- 10 deg, 0.6 +- 0.05 m)."""
    from physdsl.compile import compile as compile_phys

    model = compile_phys(EXAMPLES / "hidden-effect" / "pendulum" / "naive.phys")
    assert {e.obs for e in track_estimates(model.scene)} == {"bob.position", "hinge.angle"}
    problem, x = make_problem(model, jax.random.PRNGKey(0), 1)
    start = data_start(problem, x[0])
    from physdsl.infer.multistart import _scalar_values

    values = _scalar_values(problem, start)
    assert abs(values["hinge.initial"] - np.radians(40)) < 0.01
    assert abs(values["L"] - 0.6) < 0.01
