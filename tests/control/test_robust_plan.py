"""A plan made over posterior draws (``--posterior``): the held unknowns take the draws' values in
the rollout. With every draw of the drag coefficient at c0 the robust plan must be the plan of
the scene where the coefficient is known to be c0 (and differ from the drag-free aim)."""
from __future__ import annotations

import numpy as np
import pytest

import physdsl
from physdsl.control import build, optimise
from physdsl.infer.posterior_data import from_dict

SCENE = """
scene throw {
  world { timestep: 5 ms  duration: 0.6 s  integrator: rk4 }
  body ball {
    shape: sphere(radius: 11 cm)
    mass: 0.42 kg
    position: (0, 0, 1) m
    velocity ~ normal((4, 0, 4) m/s, 3 m/s)
  }
  effect linear_drag on ball { coefficient DRAG }
  goal {
    ball.position at 0.5 s -> (2, 0.5, 1.2) m within 1 cm
    decide: ball.velocity
  }
}
"""
C0 = 0.05  # kg/s
NAME = "linear_drag@ball.coefficient"


@pytest.mark.slow  # ~14 s
def test_a_plan_over_identical_draws_is_the_plan_for_that_value():
    fitted = physdsl.compile(SCENE.replace("DRAG", "~ half_normal(0.1 kg/s)"))
    draws = from_dict({"posterior": {NAME: np.full((2, 3), C0)}})
    robust = build(fitted, fitted.scene.goal, idata=draws, draws=6)
    assert robust.rows.shape[0] == 6
    known = physdsl.compile(SCENE.replace("DRAG", f": {C0} kg/s"))
    v_robust = optimise(robust, screened=4, refined=1).values["ball.velocity"]
    v_known = optimise(build(known, known.scene.goal), screened=4, refined=1).values["ball.velocity"]
    np.testing.assert_allclose(v_robust, v_known, atol=1e-6)
    # the drag is felt: without it the aim would differ by more than the tolerance allows
    free = np.array([2.0 / 0.5, 0.5 / 0.5, (0.2 + 9.81 * 0.5 ** 2 / 2) / 0.5])
    assert np.linalg.norm(v_robust - free) > 0.05
