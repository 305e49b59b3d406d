"""A struck ball slides, rolls and stops under Coulomb friction and rolling resistance: the
stopping distance and its derivative match the analytic law and finite differences taken
across the slip-to-roll and roll-to-rest transitions, and the ball at rest stays at rest
(rolling resistance's smoothed torque is integrated explicitly; too narrow a smoothing made
its angular velocity flip sign every step, growing x2.5 per step, and the derivatives with it)."""
import jax
import jax.numpy as jnp
import numpy as np

import physdsl  # noqa: F401 - float64
from physdsl.expr import Const, Ref, Vec
from physdsl.physics import build_simulator
from physdsl.scene import Body, Shape
from scenes import c, effect, gravity, scene, sphere

R, MU, ROLL, V0, G = 0.028575, 0.2, 4e-3, 0.5, 9.81


def stopping_distance(v0):
    """Slides (decelerating by mu g, spun up by the torque (mu r - l) m g on I = 2/5 m r^2)
    until v = r w, then rolls, decelerating by 5 l g / (7 r); quadratic in v0."""
    t1 = v0 / (MU * G + 2.5 * (MU * R - ROLL) * G / R)
    v1 = v0 - MU * G * t1
    return v0 * t1 - 0.5 * MU * G * t1**2 + v1**2 / (2 * 5 * ROLL * G / (7 * R))


def test_struck_ball_stops_where_the_law_says_with_a_finite_derivative():
    table = Body("table", Shape("plane", {"normal": c((0, 0, 1))}), position=c((0, 0, 0)), fixed=True)
    ball = sphere("ball", r=R, mass=0.21, pos=(0, 0, R), vel=Vec((Ref("v0"), Const(0.0), Const(0.0))))
    s = scene([table, ball], effects=[
        gravity(), effect("contact_friction", ("table", "ball"), coefficient=MU),
        effect("rolling_resistance", ("table", "ball"), coefficient=ROLL)],
        contact_pairs=[("table", "ball")], dt=1e-3, duration=0.7)  # at rest from ~0.45 s
    sim = build_simulator(s)

    def run(v0):
        out = sim.simulate({"v0": v0})
        return out.body_pos[-1, 1, 0], out.body_angvel[:, 1, 1]

    f = jax.jit(run)
    x_end, w = (np.asarray(a) for a in f(jnp.asarray(V0)))
    np.testing.assert_allclose(x_end, stopping_distance(V0), rtol=0.02)
    rest = np.abs(w[-200:])  # the last 0.2 s, at rest: the spin dies away, never grows
    assert np.all(rest[1:] <= rest[:-1] + 1e-12) and rest.max() < 1e-6  # rad/s

    dx = float(jax.jit(jax.jacfwd(lambda v: run(v)[0]))(jnp.asarray(V0)))
    h = 0.02  # moves both transitions by several steps
    fd = float((f(jnp.asarray(V0 + h))[0] - f(jnp.asarray(V0 - h))[0]) / (2 * h))
    assert np.isfinite(dx) and abs(dx) < 10.0
    np.testing.assert_allclose(dx, fd, rtol=5e-3)
    np.testing.assert_allclose(dx, 2 * stopping_distance(V0) / V0, rtol=0.03)  # d ~ v0^2
