"""Gradients of rollouts w.r.t. unknowns match central finite differences (float64, rel < 1e-3);
simulate is jit/vmap/grad-able and does not recompile for new values."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401
from physdsl.expr import Binary, Const, Ref, Vec
from physdsl.physics import build_simulator
from physdsl.scene import Body, Joint, Shape
from scenes import c, e, effect, gravity, scene

TIMES = np.array([0.0, 0.1, 0.2])


def free_ball_scene():
    """A free ball under many body effects; every number of interest is an unknown."""
    ball = Body("ball", Shape("sphere", {"radius": Ref("r")}), mass=Ref("m"), position=Ref("x0"),
                velocity=Ref("v0"), angular_velocity=Ref("w0"))
    effects = [
        gravity(),
        effect("linear_drag", "ball", coefficient="b"),
        effect("quadratic_drag", "ball", coefficient="cq"),
        effect("wind", "ball", velocity="wind", coefficient=0.01),
        effect("magnus", "ball", coefficient="S"),
        effect("buoyancy", "ball", fluid_density="rho"),
        effect("spring", "ball", stiffness="k", rest_length="l0", anchor=(0.0, 0.0, 2.0),
               attachment=(0.0, 0.0, 0.05)),
        effect("damper", "ball", coefficient="cd", anchor=(0.0, 0.0, 2.0), attachment=(0.0, 0.0, 0.05)),
        effect("constant_force", "ball", force="F", torque=(0.0, 0.0, 0.0)),
        effect("control_force", "ball", gain=1.0, values="u", tables={"times": TIMES}),
    ]
    return scene([ball], effects=effects, dt=5e-3, duration=0.3, integrator="rk4")


FREE_VALUES = {
    "r": 0.1, "m": 0.5, "x0": np.array([0.1, 0.0, 1.0]), "v0": np.array([2.0, 0.5, 3.0]),
    "w0": np.array([0.0, 5.0, 1.0]), "b": 0.05, "cq": 0.01, "wind": np.array([1.0, 0.0, 0.0]),
    "S": 0.002, "rho": 1.2, "k": 3.0, "l0": 0.5, "cd": 0.2, "F": np.array([0.1, 0.0, 0.2]),
    "u": np.array([[0.1, 0.2, 0.0], [0.0, -0.3, 0.1], [0.2, 0.0, 0.0]]),
}


def arm_scene():
    """Two-link arm (hinge + slider-free) with joint effects; link length, inertia, damping unknown."""
    L = Ref("L")
    link0 = Body("l0", Shape("capsule", {"radius": Const(0.02), "length": L}), mass=Ref("m0"),
                 position=Vec((Const(0.0), Const(0.0), Binary("*", Const(-0.5), L))))
    link1 = Body("l1", Shape("sphere", {"radius": Const(0.05)}), mass=Const(0.3),
                 inertia=Ref("I1"), position=Vec((Const(0.0), Const(0.0), Binary("-", Const(-0.1), L))))
    joints = [Joint("j0", "hinge", "world", "l0", axis=c((0, 1, 0)), anchor=c((0, 0, 0)),
                    initial=Ref("th0"), initial_velocity=Ref("om0")),
              Joint("j1", "hinge", "l0", "l1", axis=Ref("ax1"),
                    anchor=Vec((Const(0.0), Const(0.0), Binary("*", Const(-1.0), L))),
                    initial=Const(0.3))]
    effects = [gravity(), effect("joint_damping", "j0", coefficient="bj"),
               effect("joint_friction", "j1", torque="Tf", smoothing=0.5),
               effect("control_force", "j0", gain="gain", values="tau",
                      tables={"times": TIMES})]
    return scene([link0, link1], joints, effects, dt=5e-3, duration=0.3, integrator="rk4")


ARM_VALUES = {"L": 0.4, "m0": 0.6, "I1": np.array([1e-3, 2e-3, 1.5e-3]), "th0": 0.5, "om0": -0.3,
              "ax1": np.array([0.0, 1.0, 0.2]), "bj": 0.05, "Tf": 0.02, "gain": 1.5,
              "tau": np.array([0.1, -0.2, 0.05])}


def loss_fn(sim, weights):
    def loss(values):
        out = sim.simulate(values)
        return (jnp.sum(weights[0] * out.body_pos) + jnp.sum(weights[1] * out.body_vel)
                + 0.1 * jnp.sum(out.body_quat[:, :, 1:] ** 2))
    return loss


class Compiled:
    """One simulator with its jitted loss and gradient, shared by the tests of a module so each
    scene compiles once (compilation dominates these tests' cost)."""

    def __init__(self, s, values):
        self.sim = build_simulator(s)
        self.values = {k: jnp.asarray(v, float) for k, v in values.items()}
        rng = np.random.default_rng(0)
        T, B = len(self.sim.times), len(self.sim.body_names)
        w = (jnp.asarray(rng.normal(size=(T, B, 3))), jnp.asarray(rng.normal(size=(T, B, 3))))
        self.traces = 0  # traces of the loss (each jit trace of loss or grad calls it once)

        def loss(values):
            self.traces += 1
            return loss_fn(self.sim, w)(values)

        self.loss = jax.jit(loss)
        self.grad = jax.jit(jax.grad(loss))


def check_fd(c: Compiled, rtol=1e-3, only=None):
    """Every scalar of every unknown (or of ``only``): gradient vs central finite difference."""
    vals, loss = c.values, c.loss
    g = c.grad(vals)
    for name, x in vals.items():
        if only is not None and name not in only:
            continue
        flat = np.asarray(x).ravel()
        for i in range(flat.size):
            h = 1e-6 * max(abs(flat[i]), 1e-2)
            up, dn = flat.copy(), flat.copy()
            up[i] += h
            dn[i] -= h
            fu = loss({**vals, name: jnp.asarray(up.reshape(np.shape(x)))})
            fdn = loss({**vals, name: jnp.asarray(dn.reshape(np.shape(x)))})
            fd = float(fu - fdn) / (2 * h)
            ad = float(np.asarray(g[name]).ravel()[i])
            assert np.isfinite(ad), name
            assert abs(ad - fd) <= rtol * max(abs(fd), 1e-3), (name, i, ad, fd)


def euler(s):
    """``s`` stepped by semi-implicit Euler: half the compile cost of RK4 for the fast suite (the
    slow suite checks the RK4 scenes with every unknown)."""
    return dataclasses.replace(s, world=dataclasses.replace(s.world, integrator="semi_implicit_euler"))


@pytest.fixture(scope="module")
def free_ball():
    return Compiled(euler(free_ball_scene()), FREE_VALUES)


@pytest.fixture(scope="module")
def arm():
    return Compiled(euler(arm_scene()), ARM_VALUES)


FAST_FREE = ("m", "r", "v0", "cq", "wind", "k", "u")
FAST_ARM = ("L", "I1", "th0", "bj", "Tf", "tau")


def test_free_ball_gradients_match_finite_differences(free_ball):
    check_fd(free_ball, only=FAST_FREE)


def test_arm_gradients_match_finite_differences(arm):
    check_fd(arm, only=FAST_ARM)


@pytest.mark.slow
def test_every_unknown_gradient_matches_finite_differences():
    check_fd(Compiled(free_ball_scene(), FREE_VALUES))
    check_fd(Compiled(arm_scene(), ARM_VALUES))


@pytest.mark.slow  # ~25 s
def test_jit_vmap_grad_and_no_recompile(arm):
    sim, vals = arm.sim, arm.values
    a = sim.simulate(vals)
    traces = sim.trace_count
    b = sim.simulate({**vals, "L": jnp.asarray(0.5)})
    assert sim.trace_count == traces  # new values, same compiled function
    assert not np.allclose(a.body_pos, b.body_pos)
    Ls = jnp.array([0.3, 0.4, 0.5])
    batch = jax.vmap(lambda L: sim.simulate({**vals, "L": L}))(Ls)
    assert batch.body_pos.shape == (3,) + a.body_pos.shape
    np.testing.assert_allclose(batch.body_pos[1], a.body_pos, rtol=1e-12, atol=1e-14)
    assert a.t.shape == (len(sim.times),) and a.joint_pos.shape == (len(sim.times), 2)
    # the jitted gradient (shared with the FD test) at new values: not traced again
    g1 = arm.grad(vals)
    traces = arm.traces
    g2 = arm.grad({**vals, "L": jnp.asarray(0.45, float)})
    assert arm.traces == traces
    assert all(np.all(np.isfinite(np.asarray(x))) for x in jax.tree.leaves((g1, g2)))
    assert float(g1["L"]) != float(g2["L"]) and float(g1["L"]) != 0.0


@pytest.mark.slow
def test_contact_gradient_compliant():
    """d(final height)/d(restitution) of a compliant bounce, against finite differences."""
    from physdsl.scene import Body, Shape
    floor = Body("floor", Shape("plane", {"normal": c((0, 0, 1))}), position=c((0, 0, 0)), fixed=True)
    ball = Body("ball", Shape("sphere", {"radius": Const(0.05)}), mass=Const(0.1),
                position=Vec((Const(0.0), Const(0.0), Ref("z0"))))
    s = scene([floor, ball], effects=[gravity(), effect("restitution", ("floor", "ball"), coefficient="e")],
              contact_pairs=[("floor", "ball")], contact_model="compliant", dt=5e-4, duration=0.45)
    sim = build_simulator(s)
    f = jax.jit(lambda v: sim.simulate(v).body_pos[-1, 1, 2])
    vals = {"z0": jnp.asarray(0.3), "e": jnp.asarray(0.7)}
    g = jax.grad(f)(vals)
    for k in vals:
        h = 1e-6
        fd = (f({**vals, k: vals[k] + h}) - f({**vals, k: vals[k] - h})) / (2 * h)
        assert np.isfinite(float(g[k]))
        np.testing.assert_allclose(float(g[k]), float(fd), rtol=1e-3)
    assert float(sim.simulate(vals).contact_force.max()) > 0  # it did bounce


def test_gradients_are_finite_at_zero_velocity():
    """Norms at zero (|v| v drag, Magnus, wind at the body's velocity, smoothed joint friction at
    rest): a ball and a pendulum starting at rest give finite, FD-correct gradients."""
    ball = Body("ball", Shape("sphere", {"radius": Const(0.1)}), mass=Const(0.5),
                position=c((0.0, 0.0, 1.0)), velocity=Ref("v0"), angular_velocity=Ref("w0"))
    bob = Body("bob", Shape("sphere", {"radius": Const(0.05)}), mass=Const(0.3),
               position=c((1.0, 0.0, 0.5)))
    hinge = Joint("hinge", "hinge", "world", "bob", axis=c((0, 1, 0)), anchor=c((1.0, 0.0, 1.0)),
                  initial=Const(0.0), initial_velocity=Ref("om0"))
    effects = [gravity(), effect("quadratic_drag", "ball", coefficient="cq"),
               effect("magnus", "ball", coefficient="S"),
               effect("wind", "ball", velocity=(0.0, 0.0, 0.0), coefficient="cw"),
               effect("joint_friction", "hinge", torque="Tf", smoothing=0.1)]
    s = scene([ball, bob], [hinge], effects, dt=5e-3, duration=0.05)
    values = {"v0": np.zeros(3), "w0": np.zeros(3), "om0": 0.0, "cq": 0.01, "S": 0.002,
              "cw": 0.01, "Tf": 0.05}
    compiled = Compiled(s, values)
    g = compiled.grad(compiled.values)
    assert all(np.all(np.isfinite(np.asarray(x))) for x in jax.tree.leaves(g))
    check_fd(compiled, only=("v0", "om0", "Tf"))
