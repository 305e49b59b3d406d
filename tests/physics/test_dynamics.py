"""Rigid-body algorithms: ABA == CRBA solve, RNEA inverts ABA, M and inertia match MuJoCo."""
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl.physics import build_model
from physdsl.physics.dynamics import bias_forces, forward_dynamics, inverse_dynamics, mass_matrix
from physdsl.physics.kinematics import forward_kinematics
from physdsl.physics.params import evaluate_params
from physdsl.scene import Joint
from scenes import box, c, capsule, chain, e, scene, sphere
from mj import model_data


def mixed_tree():
    """free box, hinge/slider/ball/fixed chain hanging from world: every joint kind."""
    bodies = [
        box("base", (0.3, 0.2, 0.1), 2.0, (0, 0, 1.0)),
        capsule("arm", 0.03, 0.3, 0.7, (0.2, 0, 1.0)),
        box("slide", (0.1, 0.05, 0.05), 0.4, (0.45, 0, 1.0)),
        sphere("knob", 0.05, 0.3, (0.45, 0, 0.8)),
        sphere("tip", 0.02, 0.1, (0.45, 0.1, 0.8)),
        box("free", (0.2, 0.1, 0.05), 1.0, (1, 1, 1)),
    ]
    joints = [
        Joint("j0", "hinge", "world", "base", axis=c((0, 0.6, 0.8)), anchor=c((0, 0, 1.1)), initial=e(0.4)),
        Joint("j1", "hinge", "base", "arm", axis=c((0, 1, 0)), anchor=c((0.1, 0, 1.0)), initial=e(-0.7)),
        Joint("j2", "slider", "arm", "slide", axis=c((1, 0, 0)), initial=e(0.05)),
        Joint("j3", "ball", "slide", "knob", anchor=c((0.45, 0, 0.9)),
              initial=e((0.9, 0.1, -0.3, 0.2))),
        Joint("j4", "fixed", "knob", "tip"),
    ]
    return scene(bodies, joints)


def compute():
    """ABA, CRBA, RNEA and the kinetic-energy Hessian of the mixed tree at a random state, in one
    jitted function (one compile, shared by the tests below)."""
    s = mixed_tree()
    model = build_model(s)
    rng = np.random.default_rng(0)
    v = jnp.asarray(rng.normal(size=model.nv))
    tau = jnp.asarray(rng.normal(size=model.nv))

    @jax.jit
    def run(v, tau):
        prm = evaluate_params(s, model, {})
        q = prm["q0"]
        kin = forward_kinematics(model, prm, q, v)
        M = mass_matrix(model, kin)
        qdd_aba = forward_dynamics(model, kin, tau)

        def kinetic(v):
            k = forward_kinematics(model, prm, q, v)
            return 0.5 * jnp.einsum("bk,bkl,bl->", k.vel, k.inertia, k.vel)

        return {"M": M, "aba": qdd_aba, "crba": jnp.linalg.solve(M, tau - bias_forces(model, kin)),
                "rnea": inverse_dynamics(model, kin, qdd_aba), "tau": tau,
                "hessian": jax.hessian(kinetic)(v)}

    return {k: np.asarray(x) for k, x in run(v, tau).items()}


@pytest.fixture(scope="module")
def tree():
    return compute()


def test_aba_matches_crba_and_rnea(tree):
    np.testing.assert_allclose(tree["aba"], tree["crba"], rtol=1e-9, atol=1e-9)
    assert np.abs(tree["aba"]).max() > 0.1
    np.testing.assert_allclose(tree["rnea"], tree["tau"], atol=1e-9)
    M = tree["M"]
    assert np.all(np.linalg.eigvalsh(M) > 0)
    np.testing.assert_allclose(M, M.T, atol=1e-12)


def test_mass_matrix_is_the_hessian_of_kinetic_energy(tree):
    """M = d^2 KE / dv^2 with KE = sum_i vel_i . I_i vel_i / 2 from forward kinematics alone
    (an independent route: no Jacobians)."""
    np.testing.assert_allclose(tree["M"], tree["hessian"], atol=1e-12)


CHAIN_XML = """<mujoco><option gravity="0 0 -9.81"/><worldbody>
<body pos="0 0 0"><joint type="hinge" axis="0 1 0" pos="0 0 0"/>
 <geom type="capsule" size="0.02 0.13" pos="0 0 -0.15" mass="0.5"/>
 <body pos="0 0 -0.3"><joint type="hinge" axis="0 1 0"/>
  <geom type="capsule" size="0.02 0.13" pos="0 0 -0.15" mass="0.5"/>
  <body pos="0 0 -0.3"><joint type="hinge" axis="0 1 0"/>
   <geom type="capsule" size="0.02 0.13" pos="0 0 -0.15" mass="0.5"/>
</body></body></body></worldbody></mujoco>"""


def test_mass_matrix_and_bias_match_mujoco():
    s = chain(3, link=0.3, mass=0.5, r=0.02)
    model = build_model(s)
    prm = evaluate_params(s, model, {})
    q = np.array([0.3, -0.5, 0.8])
    v = np.array([1.0, -2.0, 0.5])

    @jax.jit
    def mass_and_bias(q, v):
        kin = forward_kinematics(model, prm, q, v)
        return mass_matrix(model, kin), bias_forces(model, kin)

    M_ours, bias = mass_and_bias(jnp.asarray(q), jnp.asarray(v))
    m, d = model_data(CHAIN_XML)
    d.qpos[:], d.qvel[:] = q, v
    mujoco.mj_forward(m, d)
    M = np.zeros((3, 3))
    mujoco.mj_fullM(m, d, M)
    np.testing.assert_allclose(M_ours, M, rtol=1e-10)
    # MuJoCo's qfrc_bias includes gravity; ours is velocity-only: compare with gravity removed
    m.opt.gravity[:] = 0
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(bias, d.qfrc_bias, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("kind,size,mjsize", [
    ("sphere", {"radius": 0.1}, "0.1"),
    ("box", {"size": (0.2, 0.4, 0.6)}, "0.1 0.2 0.3"),
    ("cylinder", {"radius": 0.05, "length": 0.4}, "0.05 0.2"),
    ("capsule", {"radius": 0.05, "length": 0.4}, "0.05 0.2"),
])
def test_shape_inertia_matches_mujoco(kind, size, mjsize):
    from physdsl.scene import Body, Shape
    b = Body("b", Shape(kind, {k: e(v) for k, v in size.items()}), density=e(700.0), position=c((0, 0, 0)))
    s = scene([b])
    prm = evaluate_params(s, build_model(s), {})
    m, _ = model_data(f'<mujoco><worldbody><body><freejoint/><geom type="{kind}" size="{mjsize}" '
                      f'density="700"/></body></worldbody></mujoco>')
    np.testing.assert_allclose(prm["mass"][0], m.body_mass[1], rtol=1e-10)
    np.testing.assert_allclose(np.diag(prm["inertia"][0]), m.body_inertia[1], rtol=1e-10)


def test_mesh_inertia_from_trimesh_matches_the_box_formula(tmp_path):
    """A closed .obj box (0.2 x 0.4 x 0.6 m, its centre off the origin), density 700: trimesh's
    mass properties give the box's mass, centre of mass and inertia."""
    from physdsl.scene import Body, Shape
    lo, hi = np.array([0.1, -0.2, 0.0]), np.array([0.3, 0.2, 0.6])
    corners = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    faces = [(1, 2, 4), (1, 4, 3), (5, 7, 8), (5, 8, 6), (1, 5, 6), (1, 6, 2),
             (3, 4, 8), (3, 8, 7), (1, 3, 7), (1, 7, 5), (2, 6, 8), (2, 8, 4)]
    path = tmp_path / "box.obj"
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in corners)
                    + "".join(f"f {a} {b} {c}\n" for a, b, c in faces))
    b = Body("b", Shape("mesh", {}, mesh_path=path), density=e(700.0), position=c((0, 0, 0)))
    s = scene([b])
    prm = evaluate_params(s, build_model(s), {})
    size = hi - lo
    m = 700.0 * np.prod(size)
    np.testing.assert_allclose(prm["mass"][0], m, rtol=1e-10)
    np.testing.assert_allclose(prm["com"][0], (lo + hi) / 2, atol=1e-12)
    Ibox = m / 12 * np.array([size[1]**2 + size[2]**2, size[0]**2 + size[2]**2, size[0]**2 + size[1]**2])
    np.testing.assert_allclose(np.asarray(prm["inertia"][0]), np.diag(Ibox), rtol=1e-9, atol=1e-12)
