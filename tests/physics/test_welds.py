"""Welded bodies merged into their core body for the dynamics (physics/welds.py): the same
motion as stepping every body, on the tree path and the recursive one, derivatives included;
the composite mass properties against the parallel-axis theorem."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import physdsl  # noqa: F401  (float64)
from physdsl import api
from physdsl.physics import build_simulator, tree, welds
from physdsl.physics.spatial import quat_to_mat

# a slider carrying two hinged links, each with a body welded to it (the second link hinged
# to the first one's sphere; a turned box on the second, with a third body welded to it), a
# block fixed in the world: nested welds, a joint under a welded body, a turned inertia, a
# static body
# (``FLOOR`` adds one contact pair, the tip over a floor: the contact-scene step)
SCENE = """
scene welded_chain {
  world { timestep: 1 ms  duration: 0.25 s  integrator: semi_implicit_euler }
  param L ~ normal(10 cm, 1 cm)
  body mount { shape: box(size: (4, 4, 2) cm)  mass: 1 kg  fixed: true  position: (0, 0, 0.03) m
               collide: false }
  body cart { shape: box(size: (6, 4, 2) cm)  mass: 300 g  position: (0, 0, 0)  collide: false }
  joint rail: slider(world -> cart) { axis: (1, 0, 0)  initial_velocity: 0.2 m/s }
  body l0 { shape: capsule(radius: 1 cm, length: 8 cm)  mass: 100 g  position: (0, 0, -0.05 m)
           collide: false }
  joint j0: hinge(cart -> l0) { axis: (0, 1, 0)  anchor: (0, 0, 0) m  initial: 0.4 rad }
  body w0 { shape: sphere(radius: 1 cm)  mass: 50 g  position: (0.02 m, 0, -0.09 m)
            orientation: (0.9, 0.3, 0.1, 0.2)  collide: false }
  joint f0: fixed(l0 -> w0)
  body l1 { shape: capsule(radius: 1 cm, length: L - 2 cm)  mass: 100 g  position: (0, 0, -0.15 m)
           collide: false }
  joint j1: hinge(w0 -> l1) { axis: (0, 1, 0)  anchor: (0, 0, -0.1) m  initial: 0.1 rad }
  body w1 { shape: box(size: (1, 2, 3) cm)  mass: 50 g  position: (-0.02 m, 0.01 m, -0.19 m)
           orientation: (0.8, 0.2, 0.5, 0.1)  collide: false }
  joint f1: fixed(l1 -> w1)
  body tip { shape: sphere(radius: 1 cm)  mass: 30 g  position: (-0.03 m, 0.02 m, -0.21 m)
             orientation: (0.7, 0.0, 0.7, 0.1) }
  joint f2: fixed(w1 -> tip)
}
"""

FLOOR = SCENE.replace("  body cart", "  body floor { shape: plane(normal: (0, 0, 1))  "
                                    "position: (0, 0, -0.4) m }\n  body cart")
FIELDS = ("body_pos", "body_quat", "body_vel", "body_angvel", "joint_pos", "joint_vel", "q", "v")


@pytest.fixture(scope="module")
def scene():
    return api.load(SCENE)


def _rollouts(scene, monkeypatch, recursive: bool, derivatives: bool = True):
    """The rollout and d(final state)/dL with the welds merged and with every body stepped."""
    if recursive:
        monkeypatch.setattr(tree, "TREE_MAX", 0)
    monkeypatch.setattr(welds, "pays", lambda core: True)  # merged wherever there are welds
    out = {}
    for label, fuse in (("merged", welds.fuse), ("every body", lambda model: None)):
        monkeypatch.setattr(welds, "fuse", fuse)
        sim = build_simulator(scene)
        values = {"L": jnp.asarray(0.1)}
        roll = sim.simulate(values)
        assert ("core" in sim.params(values)) == (label == "merged")  # the path under test
        if not derivatives:
            out[label] = (sim.model, roll, None)
            continue
        dfinal = jax.jit(jax.jacfwd(lambda L: sim.simulate({"L": L}).body_pos[-1]))(
            jnp.asarray(0.1))
        out[label] = (sim.model, roll, dfinal)
    return out


@pytest.mark.parametrize("recursive", [
    pytest.param(False, id="tree_path"),
    pytest.param(True, id="recursive_path", marks=pytest.mark.slow),  # ~30 s; the same merge
])
def test_merged_welds_move_every_body_as_stepping_each(scene, monkeypatch, recursive):
    out = _rollouts(scene, monkeypatch, recursive)
    model, merged, dmerged = out["merged"]
    _, each, deach = out["every body"]
    fused = welds._fuse(model)
    assert fused is not None and fused.core.nbody == 4  # mount, cart, l0, l1
    for f in FIELDS:
        np.testing.assert_allclose(getattr(merged, f), getattr(each, f), atol=1e-10, err_msg=f)
    moved = np.abs(np.asarray(each.body_pos[-1] - each.body_pos[0])).max(-1)
    assert moved[model.body_names.index("tip")] > 0.02  # the welded tip swung with its link
    np.testing.assert_allclose(dmerged, deach, atol=1e-9)
    assert float(jnp.max(jnp.abs(deach))) > 0.01  # L moves the bodies below it


@pytest.mark.slow  # ~20 s; the merge itself: the test above
def test_merged_welds_in_a_contact_scene_move_as_stepping_each(monkeypatch):
    """The same with one contact pair (the tip over a floor): the contact-scene step."""
    out = _rollouts(api.load(FLOOR), monkeypatch, recursive=False, derivatives=False)
    model, merged, _ = out["merged"]
    assert model.ncon == 1
    for f in FIELDS:
        np.testing.assert_allclose(getattr(merged, f), getattr(out["every body"][1], f),
                                   atol=1e-10, err_msg=f)


def test_merged_where_it_pays(scene, monkeypatch):
    """One moving core body (a pendulum's rod and bob) merges; a chain of hinges does only where
    loops are one kernel and it takes the tree path (``welds.pays``)."""
    pend = api.load(SCENE.replace("joint rail: slider(world -> cart)",
                                  "joint rail: fixed(world -> cart)")
                    .replace("  initial_velocity: 0.2 m/s", "")
                    .replace("joint j1: hinge(w0 -> l1)", "joint j1: fixed(w0 -> l1)")
                    .replace("anchor: (0, 0, -0.1) m  initial: 0.1 rad", ""))
    assert welds.fuse(build_simulator(pend).model) is not None
    chain = welds._fuse(build_simulator(scene).model).core
    monkeypatch.setattr(welds.xla_flags, "in_effect", lambda: False)
    assert not welds.pays(chain)
    monkeypatch.setattr(welds.xla_flags, "in_effect", lambda: True)
    monkeypatch.setattr(tree, "RECURSIVE_MAX", 0)
    assert welds.pays(chain)


def test_a_world_weld_is_no_merge():
    """A body welded to the world never moves: a scene with only such welds has no core."""
    sc = api.load("""
scene static_weld {
  world { timestep: 1 ms  duration: 0.01 s }
  body mount { shape: box(size: (4, 4, 2) cm)  mass: 1 kg  fixed: true }
  body bob { shape: sphere(radius: 1 cm)  mass: 50 g  position: (0, 0, -0.1 m) }
  joint h: hinge(world -> bob) { axis: (0, 1, 0)  anchor: (0, 0, 0) m }
}
""")
    assert welds.fuse(build_simulator(sc).model) is None


def test_core_mass_properties_are_the_composite(scene, monkeypatch):
    """Mass, centre and inertia of l1 + w1 + tip against the parallel-axis theorem in numpy."""
    monkeypatch.setattr(welds, "pays", lambda core: True)
    sim = build_simulator(scene)
    model = sim.model
    prm = sim.params({"L": jnp.asarray(0.1)})
    fused = welds.fuse(model)
    k = int(np.flatnonzero(fused.core_bodies == model.body_names.index("l1"))[0])
    members = [model.body_names.index(n) for n in ("l1", "w1", "tip")]
    assert sorted(np.flatnonzero(fused.root == k)) == sorted(members)
    m = np.asarray(prm["mass"])[members]
    R = np.asarray(quat_to_mat(prm["ref_quat"]))[members]
    c = (np.asarray(prm["ref_pos"])[members]
         + np.einsum("bij,bj->bi", R, np.asarray(prm["com"])[members]))
    M = m.sum()
    cc = (m[:, None] * c).sum(0) / M
    Iw = sum(R[i] @ np.asarray(prm["inertia"])[members[i]] @ R[i].T
             + m[i] * ((c[i] - cc) @ (c[i] - cc) * np.eye(3) - np.outer(c[i] - cc, c[i] - cc))
             for i in range(3))
    core = prm["core"]
    Rl = R[0]
    np.testing.assert_allclose(core["mass"][k], M, rtol=1e-14)
    ref_l1 = np.asarray(prm["ref_pos"])[members[0]]
    np.testing.assert_allclose(Rl @ np.asarray(core["com"][k]) + ref_l1, cc, atol=1e-14)
    np.testing.assert_allclose(Rl @ np.asarray(core["inertia"][k]) @ Rl.T, Iw, atol=1e-14)
    assert abs(Iw[0, 1]) > 1e-7  # the off-axis welds give products of inertia: a real check
