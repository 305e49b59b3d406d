"""Free bodies under central effects (physics/central.py): the simulator's separate translation
and rotation scans give the coupled step's states to rounding, for both integrators, with a
spinning box (anisotropic inertia: the torque-free rotation is not trivial); scenes with a
torque, a spin-dependent force or contact keep the coupled step."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl.physics import build_simulator
from physdsl.physics.central import decoupled
from physdsl.physics.integrate import State, step
from physdsl.physics.params import evaluate_params
from physdsl.scene import Body, Shape
from scenes import box, c, effect, gravity, scene, sphere


def central_scene(integrator):
    return scene([box("b", (0.2, 0.1, 0.3), 1.3, (0, 0, 1.0), orientation=c((0.9, 0.2, 0.1, 0.3)),
                      velocity=c((3.0, -0.2, 4.0)), angular_velocity=c((1.0, -2.0, 5.0))),
                  sphere("s", 0.1, 0.7, (1.0, 0.0, 2.0), vel=(-1.0, 0.5, 2.0), angvel=(3, 0, 1))],
                 effects=[gravity(), effect("quadratic_drag", "b", coefficient=0.05),
                          effect("linear_drag", "s", coefficient=0.2),
                          effect("wind", "s", velocity=(2.0, 1.0, 0.0), coefficient=0.01),
                          effect("buoyancy", "b", fluid_density=1.2)],
                 dt=0.01, duration=1.0, integrator=integrator)


def coupled_rollout(s, sim):
    """q, v of every recorded step by the coupled ``integrate.step`` (no decoupling)."""
    model = sim.model
    prm = evaluate_params(s, model, {})
    s0 = State(prm["q0"], prm["v0"], jnp.zeros(0), jnp.zeros((0, 3)))
    h = model.dt

    def record(state, i):
        state = step(model, prm, state, i * h, h)
        return state, (state.q, state.v)

    _, (q, v) = jax.jit(lambda s0: jax.lax.scan(record, s0, jnp.arange(model.nsteps)))(s0)
    return np.concatenate([prm["q0"][None], q]), np.concatenate([prm["v0"][None], v])


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_separate_scans_equal_the_coupled_step(integrator):
    s = central_scene(integrator)
    sim = build_simulator(s)
    assert decoupled(sim.model)
    r = sim.simulate({})
    q, v = coupled_rollout(s, sim)
    assert np.max(np.abs(np.asarray(r.q) - q)) < 1e-12
    assert np.max(np.abs(np.asarray(r.v) - v)) < 1e-12
    # the box tumbles (its body-frame angular velocity changes) and the drag bends the paths
    w = np.asarray(r.v)[:, 3:6]
    assert np.ptp(w, axis=0).max() > 0.5
    # positions and velocities read off the translation equal the generic observables
    assert np.allclose(np.asarray(r.body_pos)[:, 0], q[:, :3], rtol=0, atol=1e-12)
    assert np.allclose(np.asarray(r.body_vel)[:, 1], v[:, 6:9], rtol=0, atol=1e-12)


def test_torque_spin_or_contact_keep_the_coupled_step():
    ball = sphere("s", 0.1, 0.7, (0, 0, 1.0), vel=(1, 0, 0), angvel=(0, 0, 3))
    magnus = scene([ball], effects=[gravity(), effect("magnus", "s", coefficient=0.01)])
    torque = scene([ball], effects=[effect("constant_force", "s", force=(0, 0, 1))])
    floor = Body("floor", Shape("plane", {"normal": c((0, 0, 1))}), position=c((0, 0, 0)), fixed=True)
    contact = scene([ball, floor], effects=[gravity()], contact_pairs=[("floor", "s")])
    for s in (magnus, torque, contact):
        assert not decoupled(build_simulator(s).model)
    assert decoupled(build_simulator(scene([ball], effects=[gravity()])).model)
