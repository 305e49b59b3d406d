"""A box struck along the floor under compliant contact slides and stops where Coulomb's law
says, stays at rest, and its stopping distance's derivative matches the law and finite
differences taken across the stop. Compliant friction's smoothed core is an explicit damper of
rate mu fn w / eps; with eps = 1e-3 m/s narrower than one step's change of slip (h mu g / eps
= 4.9 here) the slip at rest flipped sign every step and d x / d v0 came out -1.9 (0.10 by
finite differences). Also: the widening is the same through the free-body route (closed-form
tangential inverse masses) and the Jacobian route (from the mass matrix)."""
import jax
import jax.numpy as jnp
import numpy as np

import physdsl  # noqa: F401 - float64
from physdsl.expr import Const, Ref, Vec
from physdsl.physics import build_simulator
from physdsl.physics import contact_stage as cs
from physdsl.physics.effects import zero_load
from physdsl.physics.integrate import accel, joint_mass_matrix, kinematics
from physdsl.scene import Body, Shape
from scenes import box, c, effect, gravity, scene, sphere

MU, V0, G, H = 0.5, 0.5, 9.81, 1e-3


def floor():
    return Body("floor", Shape("plane", {"normal": c((0, 0, 1))}), position=c((0, 0, 0)), fixed=True)


def test_struck_box_stops_where_the_law_says_and_rests():
    block = box("block", size=(0.1, 0.1, 0.1), mass=0.2, pos=(0, 0, 0.05 - 1e-5),
                velocity=Vec((Ref("v0"), Const(0.0), Const(0.0))))
    pair = ("floor", "block")
    s = scene([floor(), block], effects=[gravity(), effect("contact_friction", pair, coefficient=MU),
                                         effect("restitution", pair, coefficient=0.3)],
              contact_pairs=[("floor", "block")], contact_model="compliant", dt=H, duration=0.3)
    sim = build_simulator(s)  # stops after v0 / (mu g) = 0.1 s

    def run(v0):
        out = sim.simulate({"v0": v0})
        return out.body_pos[-1, 1, 0], out.body_vel[:, 1, 0]

    f = jax.jit(run)
    x_end, vx = (np.asarray(a) for a in f(jnp.asarray(V0)))
    np.testing.assert_allclose(x_end, V0**2 / (2 * MU * G), rtol=0.02)
    rest = vx[-150:]  # the last 0.15 s, at rest: the slip dies away, not flipping each step
    # (the box rocks on the compliant floor, a slow decaying mode, ~50 ms: a few sign changes)
    assert np.sum(np.sign(rest[1:]) != np.sign(rest[:-1])) <= 10, rest  # flipping: 149 of 149
    assert np.abs(rest).max() < 1e-4 and np.abs(rest[-50:]).max() < 1e-9, rest

    dx = float(jax.jit(jax.jacfwd(lambda v: run(v)[0]))(jnp.asarray(V0)))
    h = 0.02  # moves the stop by 4 steps
    fd = float((f(jnp.asarray(V0 + h))[0] - f(jnp.asarray(V0 - h))[0]) / (2 * h))
    np.testing.assert_allclose(dx, fd, rtol=2e-3)
    np.testing.assert_allclose(dx, V0 / (MU * G), rtol=0.03)


def test_widened_friction_is_the_same_through_both_routes():
    balls = [sphere(f"b{i}", r=0.05, mass=0.1 + 0.05 * i, pos=(0.09 * i, 0.01 * i, 0.045))
             for i in range(3)]  # pressed into the floor and into each other
    names = [b.name for b in balls]
    pairs = [("floor", n) for n in names] + [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    s = scene([floor()] + balls, effects=[gravity()] + [effect("contact_friction", p, coefficient=MU)
                                                       for p in pairs],
              contact_pairs=pairs, contact_model="compliant")
    sim = build_simulator(s)
    model, prm = sim.model, sim.params({})
    v = jnp.asarray(1e-3 * np.random.default_rng(0).normal(size=model.nv))  # slips ~ eps
    kin = kinematics(model, prm, prm["q0"], v, with_jac=True)
    con = cs.detect_all(model, prm, kin)
    assert int(jnp.sum(con.active)) >= 4
    load, fn = cs.compliant_load(model, kin, con, H)
    M = joint_mass_matrix(model, prm, kin)
    tau, fn2 = cs.compliant_tau(model, con._replace(inv_mass=None, inv_mass_t=None), M, v, H)
    np.testing.assert_allclose(fn2, fn, rtol=1e-10)
    base = zero_load(model)
    a_free, a_jac = accel(model, prm, kin, base + load), accel(model, prm, kin, base, tau)
    np.testing.assert_allclose(a_free, a_jac, atol=1e-9)
    a_narrow = accel(model, prm, kin, base + cs.compliant_load(model, kin, con)[0])
    assert np.abs(np.asarray(a_narrow - a_free)).max() > 1.0  # the widening acts here
