"""The vectorised tree path (physics/tree.py) against the recursive algorithms, MuJoCo, energy
conservation and finite differences; free-body compliant contact forces without the Jacobian."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl.expr import Ref
from physdsl.physics import build_simulator, tree
from physdsl.physics import contact_stage as cs
from physdsl.physics.dynamics import forward_dynamics, generalized_forces, mass_matrix
from physdsl.physics.effects import zero_load
from physdsl.physics.integrate import accel, kinematics
from physdsl.physics.kinematics import forward_kinematics
from physdsl.scene import Body, Shape
from mj import rollout as mj_rollout
from scenes import c, chain, gravity, scene, sphere
from test_dynamics import mixed_tree

FIELDS = ("pos", "quat", "com", "ang", "vcom", "vel", "jac", "bias_acc", "inertia", "acc0")


@pytest.fixture(autouse=True)
def vectorised_path(monkeypatch):
    """Every tree here takes the vectorised path: with the one-kernel options (the default)
    contact-free trees of up to ``tree.RECURSIVE_MAX`` dofs take the recursive algorithms,
    which tests/physics/test_vs_mujoco.py and test_dynamics.py check."""
    monkeypatch.setattr(tree, "RECURSIVE_MAX", 0)


@pytest.mark.parametrize("make", [mixed_tree, lambda: chain(20, link=0.1, mass=0.1, r=0.01)],
                         ids=["every_joint_kind", "chain20"])
def test_tree_path_equals_the_recursive_algorithms(make):
    """Poses, Jacobians, M and qdd of the vectorised path == forward_kinematics + CRBA/ABA."""
    sim = build_simulator(make())
    model = sim.model
    prm = sim.params({})
    rng = np.random.default_rng(3)
    q = prm["q0"] + jnp.asarray(0.4 * rng.normal(size=model.nq))
    v = jnp.asarray(rng.normal(size=model.nv))
    ref, new = forward_kinematics(model, prm, q, v), tree.tree_kinematics(model, prm, q, v)
    for f in FIELDS:
        np.testing.assert_allclose(getattr(new, f), getattr(ref, f), atol=1e-11, err_msg=f)
    np.testing.assert_allclose(tree.tree_mass_matrix(model, new), mass_matrix(model, ref),
                               atol=1e-11)
    load = zero_load(model)._replace(force=jnp.asarray(rng.normal(size=(model.nbody, 3))),
                                     torque=jnp.asarray(rng.normal(size=(model.nbody, 3))))
    qdd_ref = forward_dynamics(model, ref, generalized_forces(model, ref, load))
    qdd = tree.tree_accel(model, new, load)
    assert float(jnp.max(jnp.abs(qdd_ref))) > 1.0
    np.testing.assert_allclose(qdd, qdd_ref, rtol=1e-9, atol=1e-9)


def chain_mjcf(n):
    """``chain(n, link=0.1, mass=0.1, r=0.01)`` in MJCF, semi-implicit Euler."""
    inner = "".join(f'<body pos="0 0 {-0.1 if k else 0}"><joint type="hinge" axis="0 1 0"/>'
                    '<geom type="capsule" fromto="0 0 -0.01 0 0 -0.09" size="0.01" mass="0.1"/>'
                    for k in range(n))
    return (f'<mujoco><option timestep="0.001" integrator="Euler"/><worldbody>{inner}'
            f'{"</body>" * n}</worldbody></mujoco>')


@pytest.fixture(scope="module")
def chain5():
    s = chain(5, link=0.1, mass=0.1, r=0.01, duration=0.4, integrator="semi_implicit_euler")
    first = s.joints[0].__class__(**{**s.joints[0].__dict__, "initial": Ref("th0")})
    s = s.__class__(**{**s.__dict__, "joints": (first,) + s.joints[1:]})
    return build_simulator(s), chain_mjcf(5), {"th0": jnp.asarray(0.3)}


def test_chain_matches_mujoco(chain5):
    """5 hinged capsules swinging 0.4 s (semi-implicit Euler on both sides): joint angles."""
    sim, xml, vals = chain5
    assert tree.applies(sim.model)
    ours = np.asarray(sim.simulate(vals).q)
    qpos0 = np.zeros(5)
    qpos0[0] = float(vals["th0"])
    Q, _, _, _ = mj_rollout(xml, 400, qpos=qpos0)
    assert np.abs(Q[-1] - Q[0]).max() > 0.1  # it swings
    np.testing.assert_allclose(ours, Q, atol=1e-6)


def test_chain_conserves_energy_under_rk4():
    """Kinetic + potential energy of an RK4 chain of 5 stays constant to 1e-6 relative."""
    s = chain(5, link=0.1, mass=0.1, r=0.01, duration=0.5, integrator="rk4",
              angles=[1.0, -0.5, 0.3, 0.0, 0.2])
    sim = build_simulator(s)
    assert tree.applies(sim.model)
    roll = sim.simulate({})
    prm = sim.params({})

    def energy(q, v):
        k = kinematics(sim.model, prm, q, v)
        kin = 0.5 * jnp.einsum("bk,bkl,bl->", k.vel, k.inertia, k.vel)
        return kin + 9.81 * jnp.sum(prm["mass"] * k.com[:, 2])

    E = np.asarray(jax.vmap(energy)(roll.q, roll.v))
    swing = np.abs(np.asarray(roll.q[-1] - roll.q[0])).max()
    assert swing > 0.1
    assert np.abs(E - E[0]).max() < 1e-6 * np.abs(E).max() + 1e-9


def test_chain_gradient_matches_finite_differences(chain5):
    """d(sum of final link heights)/d(first angle): forward mode == central differences."""
    sim, _, vals = chain5
    assert tree.applies(sim.model)

    def f(th):
        return jnp.sum(sim.simulate({"th0": th}).body_pos[-1, :, 2])

    th = vals["th0"]
    g = float(jax.grad(f)(th))
    eps = 1e-6
    fd = (float(f(th + eps)) - float(f(th - eps))) / (2 * eps)
    assert abs(g) > 1e-3
    assert abs(g - fd) < 1e-6 * max(1.0, abs(fd))


@pytest.mark.slow  # ~22 s; the free-body path against MuJoCo: tests/physics/test_free_path.py
def test_free_body_compliant_load_equals_the_jacobian_route():
    """Free balls in a box: the contact forces as body loads == J^T F through the Jacobian."""
    floor = Body("floor", Shape("plane", {"normal": c((0, 0, 1))}), position=c((0, 0, 0)),
                 fixed=True)
    balls = [sphere(f"b{i}", r=0.05, mass=0.1 + 0.05 * i, pos=(0.09 * i, 0.01 * i, 0.04))
             for i in range(4)]  # pressed into the floor and into each other
    names = [b.name for b in balls]
    pairs = [("floor", n) for n in names] + [(a, b) for i, a in enumerate(names)
                                             for b in names[i + 1:]]
    sim = build_simulator(scene([floor] + balls, effects=[gravity()], contact_pairs=pairs,
                                contact_model="compliant"))
    model = sim.model
    prm = sim.params({})
    rng = np.random.default_rng(0)
    q, v = prm["q0"], jnp.asarray(0.3 * rng.normal(size=model.nv))
    kin = kinematics(model, prm, q, v, with_jac=True)
    con = cs.detect_all(model, prm, kin)
    assert int(jnp.sum(con.active)) >= 4
    tau, fn = cs.compliant_tau(model, con, None, v)
    load, fn2 = cs.compliant_load(model, kin, con)
    np.testing.assert_allclose(fn2, fn, atol=1e-12)
    base = zero_load(model)
    np.testing.assert_allclose(accel(model, prm, kin, base + load),
                               accel(model, prm, kin, base, tau), atol=1e-9)
