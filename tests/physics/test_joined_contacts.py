"""Contacts and joints: bodies joined by a joint (welded groups counted as one body) do not
collide unless a ``contact a, b`` statement asks for it, and contact candidates that never
touch leave the scene's integrator (RK4) exactly as it is without them."""
import dataclasses
import warnings

import numpy as np
import pytest

import physdsl  # noqa: F401
from physdsl.physics import build_simulator
from physdsl.scene import Body, Shape
from physdsl.syntax import loads
from scenes import c, effect, gravity, scene, sphere

# rod + bob welded, twice, hung from two hinges (the double pendulum of issue 21's report)
DOUBLE = """
scene welded_double_pendulum {{
  world {{ timestep: 1 ms  integrator: rk4  duration: 6 s }}
  body rod1 {{ shape: capsule(radius: 1 cm, length: 40 cm)  mass: 50 g  position: (0, 0, 1.3) m {collide} }}
  body bob1 {{ shape: sphere(radius: 4 cm)  mass: 500 g  position: (0, 0, 1.1) m {collide} }}
  body rod2 {{ shape: capsule(radius: 1 cm, length: 40 cm)  mass: 50 g  position: (0, 0, 0.9) m {collide} }}
  body bob2 {{ shape: sphere(radius: 4 cm)  mass: 300 g  position: (0, 0, 0.7) m {collide} }}
  joint shoulder: hinge(world -> rod1) {{
    axis: (0, -1, 0)  anchor: (0, 0, 1.5) m  initial: 60 deg  initial_velocity: 0 rad/s
  }}
  joint w1: fixed(rod1 -> bob1)
  joint elbow: hinge(bob1 -> rod2) {{
    axis: (0, -1, 0)  anchor: (0, 0, 1.1) m  initial: -30 deg  initial_velocity: 0 rad/s
  }}
  joint w2: fixed(rod2 -> bob2)
  {extra}
}}
"""


def double(collide=True, extra=""):
    text = DOUBLE.format(collide="" if collide else "collide: false", extra=extra)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no integrator fallback warning
        return loads(text)


def test_welded_groups_joined_by_a_hinge_have_no_default_contact_pairs():
    assert double().contact_pairs == ()
    pairs = double(extra="contact rod1, rod2").contact_pairs
    assert [frozenset(p) for p in pairs] == [frozenset(("rod1", "rod2"))]


def test_double_pendulum_with_default_contacts_equals_collide_false():
    """Same trajectory to 1e-9 rad over 6 s (RK4 kept, no contact between joined bodies)."""
    a = build_simulator(double()).simulate({})
    b = build_simulator(double(collide=False)).simulate({})
    assert np.max(np.abs(np.asarray(a.joint_pos) - np.asarray(b.joint_pos))) < 1e-9
    # the swing is a real one: the elbow moves by more than a radian
    assert np.ptp(np.asarray(b.joint_pos)[:, 2]) > 1.0


def _bob2_to_rod1(out):
    """Distance (T,) from bob2's centre to rod1's axis segment (the hinge to the elbow)."""
    p = np.asarray(out.body_pos)
    top, elbow, bob = np.array([0, 0, 1.5]), 2 * p[:, 0] - np.array([0, 0, 1.5]), p[:, 3]
    d = elbow - top
    s = np.clip(np.sum((bob - top) * d, -1) / np.sum(d * d, -1), 0, 1)
    return np.linalg.norm(bob - top - s[:, None] * d, axis=-1)


def test_explicit_contact_switches_a_joined_pair_back_on():
    """The elbow spun fast folds bob2 onto rod1; with ``contact rod1, bob2`` it stays at least
    its radius plus rod1's from rod1's axis."""
    fast = DOUBLE.replace("initial: -30 deg  initial_velocity: 0 rad/s",
                          "initial: -120 deg  initial_velocity: -15 rad/s")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sc = loads(fast.format(collide="", extra="contact rod1, bob2")
                   .replace("duration: 6 s", "duration: 0.4 s"))
    out = build_simulator(sc).simulate({})
    d = _bob2_to_rod1(out)
    # it comes to touch the rod (without the pair it passes through: d reaches 0.3 mm)
    assert d.min() < 0.055
    assert d.min() > 0.05 - 2e-3  # radii 4 cm + 1 cm, less the LCP's small overlap
    assert np.asarray(out.contact_force).max() > 0


def floor():
    return Body("floor", Shape("plane", {"normal": c((0, 0, 1))}), position=c((0, 0, 0)),
                fixed=True)


@pytest.mark.parametrize("model", ["lcp", pytest.param("compliant", marks=pytest.mark.slow)])
def test_thrown_ball_above_an_unreached_ground_keeps_rk4(model):
    """A ground the ball never comes near changes nothing: equal to the contact-free RK4
    rollout to 1e-12 (and RK4, not semi-implicit Euler: the two differ by far more)."""
    ball = sphere("ball", 0.11, 0.43, (0, 0, 1.8), vel=(6, 0, 6), angvel=(1, 2, 3))
    eff = [gravity(), effect("quadratic_drag", "ball", coefficient=0.01)]
    kw = dict(dt=1e-3, duration=1.0, integrator="rk4", contact_model=model)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ground = build_simulator(scene([floor(), ball], effects=eff,
                                       contact_pairs=[("floor", "ball")], **kw)).simulate({})
    free = build_simulator(scene([floor(), ball], effects=eff, **kw)).simulate({})
    s = scene([floor(), ball], effects=eff, **{**kw, "integrator": "semi_implicit_euler"})
    euler = build_simulator(s).simulate({})
    pos = np.asarray(ground.body_pos[:, 1])
    np.testing.assert_allclose(pos, np.asarray(free.body_pos[:, 1]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(ground.body_quat[:, 1]),
                               np.asarray(free.body_quat[:, 1]), rtol=0, atol=1e-12)
    assert np.max(np.abs(pos - np.asarray(euler.body_pos[:, 1]))) > 1e-4
    assert pos[:, 2].min() > 1.0  # never near the ground


def _bounce(t, z0=1.0, r=0.05, e=0.8, g=9.81):
    """Height of a ball dropped from rest at z0 onto z = r with restitution e, at times t."""
    out, t0, h0, v0 = [], 0.0, z0, 0.0
    for ti in t:
        while ti > (tc := t0 + (v0 + np.sqrt(v0**2 + 2 * g * (h0 - r))) / g):
            t0, h0, v0 = tc, r, -e * (v0 - g * (tc - t0))
        out.append(h0 + v0 * (ti - t0) - 0.5 * g * (ti - t0) ** 2)
    return np.array(out)


def test_rk4_scene_still_bounces():
    """With RK4 chosen, a dropped ball bounces as the analytic bounce to 1e-8 m over 1 s (the
    step with an impact: flight to the impact, the impulse, RK4 for the rest); semi-implicit
    Euler's contact step leaves its end gap h^2 g / 2 low (measured 2.9e-5 m)."""
    ball = sphere("ball", 0.05, 0.06, (0, 0, 1.0))
    eff = [gravity(), effect("restitution", ("floor", "ball"), coefficient=0.8)]
    s = scene([floor(), ball], effects=eff, contact_pairs=[("floor", "ball")], dt=1e-3,
              duration=1.0)
    z = {}
    for integ in ("semi_implicit_euler", "rk4"):
        s2 = dataclasses.replace(s, world=dataclasses.replace(s.world, integrator=integ))
        out = build_simulator(s2).simulate({})
        z[integ] = np.asarray(out.body_pos[:, 1, 2])
    exact = _bounce(np.asarray(out.t))
    assert z["rk4"].min() > 0.05 - 2e-3 and z["rk4"][-1] > 0.06  # bounced, not through
    np.testing.assert_allclose(z["rk4"], exact, atol=1e-8)
    np.testing.assert_allclose(z["semi_implicit_euler"], exact, atol=1e-4)


@pytest.mark.slow  # compiles the vmapped contact step (~45 s)
def test_batched_contact_steps_equal_unbatched():
    """Under vmap the contact step runs only where some member has a contact near
    (``integrate.either``): a batch of one ball that bounces and one that never reaches the
    floor gives each member's own rollout and forward-mode derivative."""
    import jax
    import jax.numpy as jnp

    ball = sphere("ball", 0.05, 0.06, (0, 0, "z0"), vel=(0, 0, "w0"))
    eff = [gravity(), effect("restitution", ("floor", "ball"), coefficient=0.8)]
    sim = build_simulator(scene([floor(), ball], effects=eff, contact_pairs=[("floor", "ball")],
                                dt=1e-3, duration=0.4, integrator="semi_implicit_euler"))

    def z(p):
        return sim.simulate({"z0": p[0], "w0": p[1]}).body_pos[:, 1, 2]

    def z_and_jac(p):
        return z(p), jax.jacfwd(z)(p)

    ps = jnp.array([[0.3, -1.0], [3.0, 2.0]])
    zs, js = jax.jit(jax.vmap(z_and_jac))(ps)
    one = jax.jit(z_and_jac)
    for i in range(2):
        zi, ji = one(ps[i])
        np.testing.assert_allclose(zs[i], zi, rtol=0, atol=1e-12)
        np.testing.assert_allclose(js[i], ji, rtol=0, atol=1e-9)
    assert zs[0].min() < 0.06 and zs[0][-1] > 0.06  # the first one bounced
    assert zs[1].min() > 1.0
