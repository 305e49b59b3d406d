"""The learned residual force in the language: its weights are one unknown sized by ``hidden``,
all-zero weights are exactly "off", and its rollout's gradient matches finite differences."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl
from physdsl.physics.effects.residual_force import SIZES, weights_size
from physdsl.physics.simulator import build_simulator
from physdsl.syntax.learned import LEARNED

BALL = """scene s {{
  world {{ timestep: 10 ms  integrator: rk4 }}
  body ball {{ shape: sphere(radius: 5 cm)  mass: 200 g  position: (0, 0, 1) m  velocity: (3, 0, 4) m/s }}
  {effect}
}}
"""
PENDULUM = """scene p {{
  world {{ timestep: 10 ms  integrator: rk4 }}
  body bob {{ shape: sphere(radius: 5 cm)  mass: 1 kg  position: (0, 0, -1) m }}
  joint hinge: hinge(world -> bob) {{ anchor: (0, 0, 0) m  axis: (0, 1, 0)  initial: 0.8 rad }}
  {effect}
}}
"""
RESIDUAL = "effect residual_force on ball { scale: 0.5 N  hidden: 8 }"
JOINT = "effect residual_joint_force on hinge { scale: 2 N*m  span: 1 rad  rate: 3 rad/s  hidden: 4 }"


def test_the_weights_are_one_unknown_sized_by_hidden():
    scene = physdsl.load(BALL.format(effect=RESIDUAL))
    (u,) = scene.unknowns
    assert u.name == "residual_force@ball.weights"
    assert u.shape == (weights_size(8, 8, 3),) == (99,)
    (j,) = physdsl.load(PENDULUM.format(effect=JOINT)).unknowns
    assert j.shape == (weights_size(2, 4, 1),) == (17,)
    assert LEARNED == SIZES  # the language sizes the weights as the physics unravels them


@pytest.mark.parametrize("field, message", [
    ("hidden: 0", "'hidden' of residual_force must be a whole number of units from 1 to 256"),
    ("hidden: 2.5", "whole number"),
    ("weights: 0", "the weights of residual_force are learned, not written"),
])
def test_bad_hidden_or_written_weights_are_errors_at_the_line(field, message):
    text = BALL.format(effect="effect residual_force on ball { " + field + " }")
    with pytest.raises(physdsl.PhysError) as err:
        physdsl.load(text)
    assert message in str(err.value)
    assert ":4:" in str(err.value)  # the effect's line


def _final(scene_text, name):
    scene = physdsl.load(scene_text)
    sim = build_simulator(scene)
    return lambda w: sim.simulate({name: w}).q[-1]


@pytest.mark.parametrize("which", ["body", "joint"])
def test_zero_weights_are_off(which):
    """All-zero weights give zero force: the rollout is the scene's without the effect (to
    rounding: XLA may fuse the zero load's additions differently)."""
    base, effect, name, n = ((BALL, RESIDUAL, "residual_force@ball.weights", 99) if which == "body"
                             else (PENDULUM, JOINT, "residual_joint_force@hinge.weights", 17))
    plain = build_simulator(physdsl.load(base.format(effect=""))).simulate({}).q
    q = build_simulator(physdsl.load(base.format(effect=effect))).simulate({name: jnp.zeros(n)}).q
    assert float(jnp.max(jnp.abs(q - plain))) <= 1e-14


@pytest.mark.parametrize("which", ["body", pytest.param("joint", marks=pytest.mark.slow)])
def test_the_rollout_gradient_matches_finite_differences(which):
    """The final state's derivative along a random direction of the weights (forward mode, as
    the Gauss-Newton fit takes it) against central differences, in float64."""
    if which == "body":
        f, n = _final(BALL.format(effect=RESIDUAL), "residual_force@ball.weights"), 99
    else:
        f, n = _final(PENDULUM.format(effect=JOINT), "residual_joint_force@hinge.weights"), 17
    rng = np.random.default_rng(0)
    w, dw = (jnp.asarray(rng.normal(0.0, 0.5, n)) for _ in range(2))
    assert float(jnp.max(jnp.abs(f(w) - f(jnp.zeros(n))))) > 1e-3  # the learned force acts
    _, tangent = jax.jvp(f, (w,), (dw,))
    fd = (f(w + 1e-6 * dw) - f(w - 1e-6 * dw)) / 2e-6
    np.testing.assert_allclose(np.asarray(tangent), np.asarray(fd), rtol=1e-5, atol=1e-8)
