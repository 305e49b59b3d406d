"""Control to a goal (issue 17): the chosen decisions and control sequences against analytic
optima, and the cost's gradient through a contact against finite differences (float64)."""
from __future__ import annotations

import jax
import numpy as np
import pytest

import physdsl
from physdsl.control import build, optimise
from physdsl.control.output import planned_scene
from physdsl.control.problem import cost_fn
from physdsl.goal import Effort, Goal, Reach

G = 9.81

THROW = """
scene throw {
  world { timestep: 5 ms  duration: 0.6 s  integrator: rk4 }
  body ball {
    shape: sphere(radius: 11 cm)
    mass: 0.42 kg
    position: (0, 0, 1) m
    velocity ~ normal((4, 0, 4) m/s, 3 m/s)
  }
  goal {
    ball.position at 0.5 s -> (2, 0.5, 1.2) m within 1 cm
    decide: ball.velocity
  }
}
"""

CART = """
scene cart {
  world { timestep: 10 ms  duration: 1 s  integrator: rk4 }
  body cart { shape: box(size: (20, 10, 10) cm)  mass: 2 kg  position: (0, 0, 0.5) m }
  joint rail: slider(world -> cart) { axis: (1, 0, 0)  initial: 0 m  initial_velocity: 0 m/s }
  control push on rail {
    times: (0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9) s
    values ~ uniform(-20 N, 20 N)
  }
}
"""


def test_a_throw_is_aimed_at_a_point_as_ballistics_says(tmp_path):
    model = physdsl.compile(THROW)
    assert model.scene.goal == Goal((Reach("ball", 0.5, (2.0, 0.5, 1.2), 0.01),),
                                    decisions=("ball.velocity",))
    problem = build(model, model.scene.goal)
    plan = optimise(problem, screened=4, refined=1)
    t = 0.5
    exact = np.array([2.0 / t, 0.5 / t, (0.2 + G * t * t / 2) / t])
    assert plan.met
    np.testing.assert_allclose(plan.values["ball.velocity"], exact, atol=1e-4)
    # the planned scene: the velocity written in, nothing left to decide or infer
    planned = physdsl.load(planned_scene(problem, plan, tmp_path))
    assert planned.unknowns == () and planned.goal.decisions == ()
    np.testing.assert_allclose(planned.body("ball").velocity.array(), exact, atol=1e-6)


def test_a_push_that_meets_the_goal_spends_less_effort_than_a_constant_one():
    """Minimum ∫u² moving a mass m by X in T is the ramp u = c (T - t): 3 m² X² / T³, three
    quarters of the constant push's 4 m² X² / T³; the held steps of 0.1 s come close to it."""
    model = physdsl.compile(CART)
    m, x, T = 2.0, 0.5, 1.0
    goal = Goal((Reach("cart", T, (x, 0.0, 0.5), 0.002), Effort(1e-2)))
    plan = optimise(build(model, goal), screened=4, refined=1)
    u = plan.values["control_force@rail.values"]
    assert plan.met
    assert plan.errors[1] < 0.85 * 4 * m * m * x * x / T ** 3
    assert np.all(np.diff(u) < 0.0), u  # a falling ramp, as the optimum
    assert np.all(np.abs(u) <= 20.0)  # inside the prior's support, by construction


def test_an_unknown_named_as_decision_must_exist():
    model = physdsl.compile(THROW)
    with pytest.raises(physdsl.ModelError, match="not an unknown"):
        build(model, Goal((Reach("ball", 0.5, (1, 0, 1), 0.01),), decisions=("ball.mass",)))
    with pytest.raises(physdsl.ModelError, match="neither a body nor a marker"):
        build(model, Goal((Reach("bal", 0.5, (1, 0, 1), 0.01),), decisions=("ball.velocity",)))
    with pytest.raises(physdsl.ModelError, match="outside the simulated"):
        build(model, Goal((Reach("ball", 2.0, (1, 0, 1), 0.01),), decisions=("ball.velocity",)))


POOL = """
scene pool {
  world { timestep: 2 ms  duration: 0.3 s }
  param r: 28.575 mm
  param vx ~ normal(1 m/s, 0.2 m/s)
  param vy ~ normal(0.1 m/s, 0.05 m/s)
  ground table { normal: (0, 0, 1)  point: (0, 0, 0) m }
  body cue {
    shape: sphere(radius: r)
    mass: 170 g
    position: (0, 0, r)
    velocity: (vx, vy, 0 m/s)
    angular_velocity: (-vy / r, vx / r, 0 rad/s)
  }
  body object { shape: sphere(radius: r)  mass: 170 g  position: (0.1 m, 2 cm, r) }
  contact table, cue { friction: 0.2 }
  contact table, object { friction: 0.2 }
}
"""


@pytest.mark.slow  # compiling the contact rollout and its Jacobian: minutes on a loaded CPU
def test_the_cost_gradient_through_a_collision_matches_finite_differences():
    model = physdsl.compile(POOL)
    goal = Goal((Reach("object", 0.3, (0.35, 0.0, 0.028575), 0.01),), decisions=("vx", "vy"))
    problem = build(model, goal)
    cost = jax.jit(cost_fn(problem))
    z = problem.start  # 1 m/s, 0.1 m/s: the cue hits the object ball at about 0.04 s
    grad = np.asarray(jax.grad(cost_fn(problem))(z))
    h = 1e-6
    fd = [(float(cost(z + h * e)) - float(cost(z - h * e))) / (2 * h) for e in np.eye(len(z))]
    assert np.all(np.abs(grad) > 1.0)  # the collision moves the object ball: not a flat spot
    np.testing.assert_allclose(grad, fd, rtol=1e-4)
