"""Closed-form checks: projectile (with/without linear drag), pendulum period, double-pendulum
energy (RK4), slider spring oscillator."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401
from physdsl.physics import build_simulator
from physdsl.physics.dynamics import mass_matrix
from physdsl.physics.kinematics import forward_kinematics
from physdsl.scene import Joint
from scenes import c, chain, effect, gravity, pendulum, scene, sphere

X0, V0, M = np.array([0.0, 0.0, 1.0]), np.array([3.0, 1.0, 5.0]), 0.5


@pytest.mark.parametrize("integrator,tol", [("rk4", 1e-10),
                                            pytest.param("semi_implicit_euler", 6e-3, marks=pytest.mark.slow)])
def test_projectile(integrator, tol):
    s = scene([sphere("ball", mass=M, pos=X0, vel=V0)], effects=[gravity()], duration=1.0,
              dt=1e-3, integrator=integrator)
    r = build_simulator(s).simulate({})
    t = np.asarray(r.t)[:, None]
    exact = X0 + V0 * t + 0.5 * np.array([0, 0, -9.81]) * t**2
    np.testing.assert_allclose(r.body_pos[:, 0], exact, atol=tol)
    np.testing.assert_allclose(r.body_vel[:, 0], V0 + np.array([0, 0, -9.81]) * t, atol=1e-9)


def test_projectile_linear_drag():
    b = 0.3
    s = scene([sphere("ball", mass=M, pos=X0, vel=V0)],
              effects=[gravity(), effect("linear_drag", "ball", coefficient=b)],
              duration=1.0, dt=1e-3, integrator="rk4")
    r = build_simulator(s).simulate({})
    t = np.asarray(r.t)[:, None]
    g = np.array([0, 0, -9.81])
    vinf = M * g / b
    exact = X0 + vinf * t + (V0 - vinf) * (M / b) * (1 - np.exp(-b * t / M))
    np.testing.assert_allclose(r.body_pos[:, 0], exact, atol=1e-10)


def zero_crossings(t, x):
    i = np.nonzero((x[:-1] > 0) & (x[1:] <= 0))[0]
    return t[i] + x[i] / (x[i] - x[i + 1]) * (t[i + 1] - t[i])


def test_pendulum_small_angle_period():
    L, r, m = 0.8, 0.01, 0.4
    sim = build_simulator(pendulum(length=L, mass=m, r=r, angle=0.01, duration=4.0, dt=1e-3))
    out = sim.simulate({})
    cross = zero_crossings(np.asarray(out.t), np.asarray(out.joint_pos[:, 0]))
    I = m * L**2 + 0.4 * m * r**2
    T = 2 * np.pi * np.sqrt(I / (m * 9.81 * L))
    # small-angle period; the finite amplitude correction is (1 + theta0^2/16) ~ 6e-6
    np.testing.assert_allclose(np.diff(cross).mean(), T, rtol=2e-5)


def energy(model, prm, q, v):
    kin = forward_kinematics(model, prm, q, v)
    Mq = mass_matrix(model, kin)
    pe = -jnp.sum(prm["mass"][:, None] * kin.com * jnp.array([0, 0, -9.81]))
    return 0.5 * v @ Mq @ v + pe


@pytest.mark.parametrize("dt,tol", [(1e-3, 1e-7), pytest.param(1e-2, 1e-3, marks=pytest.mark.slow)])
def test_double_pendulum_energy_rk4(dt, tol):
    """Undamped double pendulum from 90 and 45 degrees for 2 s: relative energy drift < tol."""
    s = chain(2, link=0.5, mass=1.0, r=0.03, angles=[np.pi / 2, np.pi / 4], dt=dt, duration=2.0)
    sim = build_simulator(s)
    out = sim.simulate({})
    prm = sim.params({})
    E = jax.jit(jax.vmap(lambda q, v: energy(sim.model, prm, q, v)))(out.q, out.v)
    scale = float(jnp.max(jnp.abs(E - E[0]))) / float(jnp.abs(E[0]))
    assert scale < tol, scale
    assert float(jnp.std(out.v[:, 1])) > 1.0  # it really swings


def test_slider_spring_oscillator():
    k, m, A, L0 = 40.0, 0.5, 0.1, 0.3
    block = sphere("block", r=0.05, mass=m, pos=(0, 0, 0))
    j = Joint("rail", "slider", "world", "block", axis=c((1, 0, 0)), initial=c(A))
    sp = effect("spring", "block", stiffness=k, rest_length=L0, anchor=(-L0, 0, 0),
                attachment=(0, 0, 0))
    s = scene([block], [j], [gravity(), sp], dt=1e-3, duration=2.0, integrator="rk4")
    out = build_simulator(s).simulate({})
    w = np.sqrt(k / m)
    np.testing.assert_allclose(out.joint_pos[:, 0], A * np.cos(w * np.asarray(out.t)), atol=1e-9)


def test_slider_joint_spring_oscillator():
    """A joint spring on a horizontal slider: x = rest + (A - rest) cos(sqrt(k/m) t)."""
    k, m, A, rest = 40.0, 0.5, 0.1, 0.02
    block = sphere("block", r=0.05, mass=m, pos=(0, 0, 0))
    j = Joint("rail", "slider", "world", "block", axis=c((1, 0, 0)), initial=c(A))
    sp = effect("joint_spring", "rail", stiffness=k, rest=rest)
    s = scene([block], [j], [gravity(), sp], dt=1e-3, duration=2.0, integrator="rk4")
    out = build_simulator(s).simulate({})
    expected = rest + (A - rest) * np.cos(np.sqrt(k / m) * np.asarray(out.t))
    np.testing.assert_allclose(out.joint_pos[:, 0], expected, atol=1e-9)


def test_joint_spring_on_a_ball_joint_is_refused():
    from physdsl.errors import ModelError

    bob = sphere("bob", r=0.05, mass=0.2, pos=(0, 0, 0.5))
    j = Joint("socket", "ball", "world", "bob", anchor=c((0, 0, 1.0)))
    with pytest.raises(ModelError, match="hinges and sliders"):
        build_simulator(scene([bob], [j], [gravity(), effect("joint_spring", "socket", stiffness=1.0)]))
