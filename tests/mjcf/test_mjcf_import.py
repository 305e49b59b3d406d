"""`physdsl import`: MJCF and URDF models become scenes that lint, are in `fmt` form, and roll
out as MuJoCo simulates the original file (RK4 on both sides, float64)."""
import numpy as np

import physdsl
from physdsl.cli import main
from physdsl.physics import build_simulator
from physdsl.syntax import edit, format_source

from mjcf_helpers import DATA, import_scene, joints, mujoco_rollout


def _check_text(path):
    text = path.read_text()
    assert format_source(text) == text  # canonical fmt form
    assert main(["lint", str(path)]) == 0
    return text


def test_cart_pole_rollout_equals_mujoco(tmp_path):
    """Cart-pole with a motor (gear 2) driven from a CSV at 50 Hz: 1 s of joint angles within 1e-9."""
    dt, T = 0.002, 500
    rng = np.random.default_rng(1)
    times = np.arange(0, 1.0, 0.02)
    force = rng.normal(0, 1.5, size=len(times))
    rows = "\n".join(f"{t:.3f},{float(f)!r}" for t, f in zip(times, force))
    (tmp_path / "controls.csv").write_text("t,push\n" + rows + "\n")
    scene_path = import_scene(tmp_path, "cart_pole.xml", "--key", "start", "--controls", "controls.csv")
    text = _check_text(scene_path)
    assert "control push on rail from \"controls.csv\" column push { gain: 2 }" in text
    assert "effect joint_damping on hinge { coefficient: 0.01 N*m*s/rad }" in text
    ctrl = lambda k: [force[min(int(k * dt / 0.02 + 1e-9), len(times) - 1)]]  # noqa: E731
    Q = mujoco_rollout((DATA / "cart_pole.xml").read_text(), T, ctrl=ctrl)
    scene = physdsl.load(scene_path)
    sim = build_simulator(scene)
    out = sim.simulate({})
    assert len(out.t) == T + 1  # no observations: the scene runs its default 1 s
    np.testing.assert_allclose(joints(sim, out, ["rail", "hinge"]), Q, atol=1e-9)
    assert np.ptp(Q[:, 0]) > 0.02 and np.ptp(Q[:, 1]) > 0.3  # the motor and gravity act
    # the site at the pole's end is a marker, where MuJoCo puts the site
    assert "marker tip on pole { position: (0, 0, -0.3) m }" in text
    import mujoco
    m = mujoco.MjModel.from_xml_path(str(DATA / "cart_pole.xml"))
    d = mujoco.MjData(m)
    tip = []
    for q in Q:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        tip.append(d.site_xpos[0].copy())
    np.testing.assert_allclose(np.asarray(out.marker_pos)[:, 0], np.array(tip), atol=1e-9)


def test_two_geoms_in_one_body(tmp_path):
    """Rod and bob in one MJCF body: a body at the centre of mass with MuJoCo's inertia, and two
    massless shape bodies welded to it; 1 s within 1e-9 rad, the bob's centre within 1e-9 m."""
    scene_path = import_scene(tmp_path, "pendulum.xml", "--key", "start")
    text = _check_text(scene_path)
    assert "joint bob_weld: fixed(pendulum -> bob)" in text
    Q = mujoco_rollout((DATA / "pendulum.xml").read_text(), 1000)
    sim = build_simulator(physdsl.load(scene_path))
    out = sim.simulate({})
    np.testing.assert_allclose(joints(sim, out, ["pivot"])[:, 0], Q[:, 0], atol=1e-9)
    a = Q[:, 0]
    bob = np.asarray(out.body_pos)[:, sim.body_names.index("bob")]
    np.testing.assert_allclose(bob, np.c_[0.6 * np.sin(a), 0 * a, 1.2 - 0.6 * np.cos(a)], atol=1e-9)


def test_urdf_two_link_arm(tmp_path):
    """URDF through MuJoCo's compiler: inertials at their origins, revolute and continuous joints,
    damping; with RK4 on both sides, 1 s within 1e-9 rad from a bent start."""
    scene_path = import_scene(tmp_path, "arm.urdf")
    text = _check_text(scene_path)
    assert "joint shoulder: hinge(world -> upper)" in text
    assert "limits: (-3, 3) rad" in text
    assert "integrator EULER: becomes semi_implicit_euler" in text
    text = edit.replace_value(text, "world.integrator", "rk4")
    text = edit.replace_value(text, "shoulder.initial", "0.8 rad")
    text = edit.replace_value(text, "elbow.initial", "-0.5 rad")
    scene_path.write_text(text)
    sim = build_simulator(physdsl.load(scene_path))
    out = sim.simulate({})
    import mujoco
    m = mujoco.MjModel.from_xml_path(str(DATA / "arm.urdf"))
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    d = mujoco.MjData(m)
    d.qpos[:] = [0.8, -0.5]
    Q = [d.qpos.copy()]
    for _ in range(len(out.t) - 1):
        mujoco.mj_step(m, d)
        Q.append(d.qpos.copy())
    np.testing.assert_allclose(joints(sim, out, ["shoulder", "elbow"]), np.array(Q), atol=1e-9)


def test_two_joints_in_one_body(tmp_path):
    """A slide then a hinge in one MJCF body: a massless frame joins them in physdsl; both sides
    and the exported MJCF (both joints back in one body) agree over 1 s within 1e-9."""
    from physdsl.mjcf import scene_to_mjcf

    scene_path = import_scene(tmp_path, "two_dof.xml", "--key", "0")
    text = _check_text(scene_path)
    assert "joint tilt: hinge(puck_dof1 -> puck)" in text
    Q = mujoco_rollout((DATA / "two_dof.xml").read_text(), 500)
    scene = physdsl.load(scene_path)
    sim = build_simulator(scene)
    ours = joints(sim, sim.simulate({}), ["slide_x", "tilt"])
    np.testing.assert_allclose(ours, Q, atol=1e-9)
    xml, _ = scene_to_mjcf(scene, {})
    np.testing.assert_allclose(mujoco_rollout(xml, 500), Q, atol=1e-9)
    assert np.ptp(Q, axis=0).min() > 0.3


def test_mesh_geom(tmp_path):
    """An inline MJCF mesh: written beside the scene as OBJ (MuJoCo's compiled vertices, in the
    geom frame), MuJoCo's mass and inertia, listed as not colliding; 1 s within 1e-9 rad, and
    the exported MJCF (mesh asset from the OBJ) rolls out the same."""
    from physdsl.mjcf import scene_to_mjcf

    scene_path = import_scene(tmp_path, "mesh_pendulum.xml", "--key", "out")
    text = _check_text(scene_path)
    assert 'shape: mesh("wedge.obj")' in text and (tmp_path / "wedge.obj").is_file()
    assert "geom '#0' (mesh): written to wedge.obj; it renders but does not collide" in text
    Q = mujoco_rollout((DATA / "mesh_pendulum.xml").read_text(), 500)
    scene = physdsl.load(scene_path)
    sim = build_simulator(scene)
    np.testing.assert_allclose(joints(sim, sim.simulate({}), ["pivot"]), Q, atol=1e-9)
    xml, notes = scene_to_mjcf(scene, {})
    assert 'type="mesh"' in xml and notes == []
    np.testing.assert_allclose(mujoco_rollout(xml, 500), Q, atol=1e-9)


def test_ball_joint(tmp_path):
    """A ball joint from rest: the centre of mass follows MuJoCo's within 1e-9 m over 1 s, and
    the exported MJCF's within 1e-9 m."""
    import mujoco
    from physdsl.mjcf import scene_to_mjcf

    scene_path = import_scene(tmp_path, "ball_joint.xml")
    assert "joint sock: ball(world -> top) { anchor: (0, 0, 1) m }" in _check_text(scene_path)
    scene = physdsl.load(scene_path)
    out = build_simulator(scene).simulate({})

    def com(m):
        d, X = mujoco.MjData(m), []
        if m.nkey:
            mujoco.mj_resetDataKeyframe(m, d, 0)
        for _ in range(len(out.t)):
            mujoco.mj_kinematics(m, d)
            X.append(d.xipos[1].copy())
            mujoco.mj_step(m, d)
        return np.array(X)

    X = com(mujoco.MjModel.from_xml_path(str(DATA / "ball_joint.xml")))
    np.testing.assert_allclose(np.asarray(out.body_pos)[:, 0], X, atol=1e-9)
    np.testing.assert_allclose(com(mujoco.MjModel.from_xml_string(scene_to_mjcf(scene, {})[0])), X,
                               atol=1e-9)
    assert np.ptp(X, axis=0).min() > 0.05
