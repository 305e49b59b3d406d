"""A spinning turntable stopped by Coulomb friction in its hinge: it stops where the law says,
its rate at rest dies away without flipping sign, and the stopping angle's derivatives match
the law and finite differences taken across the stop. Joint friction's tanh is integrated
explicitly; with its smoothing width narrower than one step's change of rate under the whole
torque (h T / (W I) = 6 here), the rate at rest flipped sign every step, growing x5 (Euler) or
x14 (RK4) per step until |rate| ~ W, and the derivatives grew without bound."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401 - float64
from physdsl.expr import Ref
from physdsl.physics import build_simulator
from physdsl.scene import Joint
from scenes import c, effect, gravity, scene, sphere

M, L, R, T, H, W = 0.1, 0.1, 0.01, 0.015, 2e-3, 5e-3
I = M * L**2 + 0.4 * M * R**2  # about the vertical hinge; gravity exerts no torque about it
W0 = 3.0  # rad/s: stops after W0 I / T = 0.2 s, at W0^2 I / (2 T) = 0.30 rad


@pytest.mark.parametrize("integrator", ["semi_implicit_euler", "rk4"])
def test_stopped_turntable_rests_and_its_derivatives_match_the_law(integrator):
    bob = sphere("bob", r=R, mass=M, pos=(L, 0, 1.0))
    hinge = Joint("hinge", "hinge", "world", "bob", axis=c((0, 0, 1)), anchor=c((0, 0, 1.0)),
                  initial=c(0.0), initial_velocity=Ref("w0"))
    friction = effect("joint_friction", "hinge", torque=Ref("T"), smoothing=W)
    sim = build_simulator(scene([bob], [hinge], [gravity(), friction], dt=H, duration=0.5,
                                integrator=integrator))

    def run(p):
        out = sim.simulate({"w0": p[0], "T": p[1]})
        return out.joint_pos[-1, 0], out.joint_vel[:, 0]

    f = jax.jit(run)
    p0 = jnp.array([W0, T])
    q_end, w = (np.asarray(a) for a in f(p0))
    np.testing.assert_allclose(q_end, W0**2 * I / (2 * T), rtol=0.02)
    rest = w[-100:]  # the last 0.2 s, at rest: the rate dies away, never flips nor grows
    assert np.abs(rest).max() < 1e-3 and np.all(rest >= 0.0)
    assert np.all(rest[1:] <= rest[:-1] + 1e-12)

    J = np.asarray(jax.jit(jax.jacfwd(lambda p: run(p)[0]))(p0))
    steps = np.array([0.05, 2e-4])  # each moves the stop by 1-2 steps
    fd = [float(f(p0 + d)[0] - f(p0 - d)[0]) / (2 * h) for d, h in zip(jnp.diag(steps), steps)]
    np.testing.assert_allclose(J, fd, rtol=2e-3)
    np.testing.assert_allclose(J, [W0 * I / T, -W0**2 * I / (2 * T**2)], rtol=0.03)
