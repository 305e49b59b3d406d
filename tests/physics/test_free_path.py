"""The free-body fast path (Newton-Euler per body, closed-form contact effective mass) equals
the general tree algorithms on the same scene, including an off-centre COM."""
import jax
import jax.numpy as jnp
import numpy as np

import physdsl  # noqa: F401  (float64)
from physdsl.physics import build_model
from physdsl.physics import contact_stage as cs
from physdsl.physics.dynamics import forward_dynamics, generalized_forces, mass_matrix
from physdsl.physics.effects import Load
from physdsl.physics.free import free_accel, free_kinematics, free_mass_matrix
from physdsl.physics.kinematics import forward_kinematics
from physdsl.physics.params import evaluate_params
from physdsl.scene import Body, Shape
from scenes import box, c, scene, sphere


def free_scene():
    floor = Body("floor", Shape("plane", {"normal": c((0, 0, 1))}), position=c((0, 0, 0)), fixed=True)
    return scene([box("b", (0.2, 0.1, 0.3), 1.3, (0, 0, 0.1), orientation=c((0.9, 0.2, 0.1, 0.3)),
                      velocity=c((0.3, -0.2, 0.1)), angular_velocity=c((1.0, -2.0, 0.5))),
                  floor,
                  sphere("s", 0.1, 0.7, (0.05, 0.02, 0.3), vel=(0.0, 0.1, -1.0), angvel=(3, 0, 1))],
                 contact_pairs=[("floor", "b"), ("b", "s"), ("floor", "s")], contact_model="compliant")


def compute():
    """Fast-path and tree quantities at a random state, in one jitted function (one compile)."""
    s = free_scene()
    model = build_model(s)
    assert model.free_bodies == (0, 2)
    rng = np.random.default_rng(0)
    v = jnp.asarray(rng.normal(size=model.nv))
    load = Load(jnp.asarray(rng.normal(size=(3, 3))), jnp.asarray(rng.normal(size=(3, 3))),
                jnp.asarray(rng.normal(size=model.nv)))
    tau = jnp.asarray(rng.normal(size=model.nv))
    # as a mesh body would have: the COM away from the body origin
    com = jnp.array([[0.02, -0.01, 0.03], [0.0, 0.0, 0.0], [-0.01, 0.02, 0.0]])

    @jax.jit
    def both(v, load, tau, com):
        prm = {**evaluate_params(s, model, {}), "com": com}
        q = prm["q0"]
        fast = free_kinematics(model, prm, q, v, with_jac=True)
        tree = forward_kinematics(model, prm, q, v)
        con = cs.detect_all(model, prm, fast)
        M = free_mass_matrix(model, prm, fast)
        return {
            "kin": ({f: getattr(fast, f) for f in FIELDS}, {f: getattr(tree, f) for f in FIELDS}),
            "accel": (free_accel(model, prm, fast, load.force, load.torque, load.joint + tau),
                      forward_dynamics(model, tree, generalized_forces(model, tree, load) + tau)),
            "mass": (M, mass_matrix(model, tree)),
            "inv_mass": (con.inv_mass, jnp.sum(con.Jn * jnp.linalg.solve(M, con.Jn.T).T, -1)),
        }

    return both(v, load, tau, com)


FIELDS = ("pos", "quat", "rot", "com", "ang", "vcom", "jac")
OUT = {}


def results():
    if not OUT:
        OUT.update(compute())
    return OUT


def test_newton_euler_equals_articulated_body_algorithm():
    r = results()
    fast, tree = r["kin"]
    for f in FIELDS:
        np.testing.assert_allclose(fast[f], tree[f], atol=1e-12, err_msg=f)
    np.testing.assert_allclose(*r["accel"], rtol=1e-10, atol=1e-10)
    assert np.abs(np.asarray(r["accel"][0])).max() > 0.1
    np.testing.assert_allclose(*r["mass"], atol=1e-12)


def test_closed_form_effective_mass_equals_the_mass_matrix_route():
    closed, ref = results()["inv_mass"]
    assert closed.shape == (6,)  # every candidate row of the three pairs (box-plane: 4 closest)
    np.testing.assert_allclose(closed, ref, rtol=1e-12)
