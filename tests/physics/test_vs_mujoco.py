"""MuJoCo as oracle: the same scene as MJCF, integrated with MuJoCo's RK4, must agree.

Tolerances are stated per test; both sides integrate the same equations with the same RK4
scheme, so differences are round-off plus (for the double pendulum) chaotic amplification.
"""
import numpy as np
import pytest

import physdsl  # noqa: F401
from physdsl.expr import Const
from physdsl.physics import build_simulator
from physdsl.scene import Body, Joint, Shape
from scenes import box, c, capsule, e, effect, gravity, scene, sphere
from mj import rollout

OPT = '<option timestep="{dt}" integrator="RK4" gravity="0 0 -9.81" {extra}/>'


def xml(body: str, dt: float, extra: str = "", tail: str = "") -> str:
    return (f'<mujoco>{OPT.format(dt=dt, extra=extra)}<worldbody>{body}</worldbody>{tail}'
            "</mujoco>")


def test_thrown_ball_quadratic_drag():
    """MuJoCo's fluid model on a non-spinning sphere is F = -c|v|v, c = rho Cd/2 pi r^2 (Cd/2 = 0.125)."""
    r, m, rho, blunt = 0.11, 0.43, 1.204, 0.125
    cq = blunt * rho * np.pi * r**2
    dt, T = 1 / 1200, 1200
    v0 = (6.5, 0.4, 6.0)
    body = (f'<body pos="0 0 1.8"><freejoint/><geom type="sphere" size="{r}" mass="{m}" '
            'fluidshape="ellipsoid" fluidcoef="0.125 0.25 1.5 1.0 1.0"/></body>')
    Q, V, X, _ = rollout(xml(body, dt, f'density="{rho}" viscosity="0"'), T,
                         qvel=np.r_[v0, 0, 0, 0])
    s = scene([sphere("ball", r, m, (0, 0, 1.8), vel=v0)],
              effects=[gravity(), effect("quadratic_drag", "ball", coefficient=cq)],
              dt=dt, duration=T * dt, integrator="rk4")
    out = build_simulator(s).simulate({})
    np.testing.assert_allclose(out.body_pos[:, 0], X[:, 1], atol=1e-9)
    drop = np.abs(X[-1, 1] - (np.array([0, 0, 1.8]) + np.array(v0) - [0, 0, 9.81 / 2])).max()
    assert drop > 0.05  # drag really matters over this horizon


def test_pendulum_rod_bob_damping():
    """pendulum_01: capsule rod welded to a sphere bob, hinge damping; angle over 3 s within 1e-8 rad."""
    dt, T, b, th0 = 1e-3, 3000, 0.004, np.deg2rad(40)
    body = ('<body pos="0 0 1.2"><joint type="hinge" axis="0 -1 0" damping="0.004"/>'
            '<geom type="capsule" fromto="0 0 0 0 0 -0.56" size="0.005" mass="0.01"/>'
            '<geom type="sphere" pos="0 0 -0.6" size="0.04" mass="0.3"/></body>')
    Q, V, X, _ = rollout(xml(body, dt), T, qpos=[th0])
    rod = capsule("rod", 0.005, 0.56, 0.01, (0, 0, 1.2 - 0.28))
    bob = sphere("bob", 0.04, 0.3, (0, 0, 0.6))
    joints = [Joint("hinge", "hinge", "world", "rod", axis=c((0, -1, 0)), anchor=c((0, 0, 1.2)),
                    initial=e(th0)),
              Joint("weld", "fixed", "rod", "bob")]
    s = scene([rod, bob], joints, [gravity(), effect("joint_damping", "hinge", coefficient=b)],
              dt=dt, duration=T * dt, integrator="rk4")
    out = build_simulator(s).simulate({})
    np.testing.assert_allclose(out.joint_pos[:, 0], Q[:, 0], atol=1e-8)
    np.testing.assert_allclose(out.joint_vel[:, 0], V[:, 0], atol=1e-7)
    # the welded bob rides on the rod: pivot + 0.6 (sin a, 0, -cos a)
    a = Q[:, 0]
    np.testing.assert_allclose(out.body_pos[:, 1], np.c_[0.6 * np.sin(a), 0 * a, 1.2 - 0.6 * np.cos(a)],
                               atol=1e-8)


def test_cart_pole_force_sequence():
    """Cart on a rail, pole on a hinge; a piecewise-constant force on the rail; 2 s within 1e-8."""
    dt, T = 1e-3, 2000
    rng = np.random.default_rng(3)
    times = np.arange(0, 2.0, 0.1)
    forces = rng.normal(0, 3.0, size=len(times))
    body = ('<body pos="0 0 0.5"><joint name="rail" type="slide" axis="1 0 0"/>'
            '<geom type="box" size="0.15 0.1 0.05" mass="1.0"/>'
            '<body pos="0 0 0"><joint type="hinge" axis="0 1 0"/>'
            '<geom type="capsule" fromto="0 0 0 0 0 0.6" size="0.02" mass="0.2"/></body></body>')
    tail = '<actuator><motor joint="rail" gear="1"/></actuator>'
    Q, V, X, _ = rollout(xml(body, dt, tail=tail), T, qpos=[0, 0.2],
                         ctrl=lambda k: [forces[min(int(k * dt / 0.1 + 1e-9), len(times) - 1)]])
    cart = box("cart", (0.3, 0.2, 0.1), 1.0, (0, 0, 0.5))
    pole = capsule("pole", 0.02, 0.6, 0.2, (0, 0, 0.8))
    joints = [Joint("rail", "slider", "world", "cart", axis=c((1, 0, 0))),
              Joint("hinge", "hinge", "cart", "pole", axis=c((0, 1, 0)), anchor=c((0, 0, 0.5)),
                    initial=e(0.2))]
    ctrl = effect("control_force", "rail", gain=1.0, tables={"times": times, "values": forces})
    s = scene([cart, pole], joints, [gravity(), ctrl], dt=dt, duration=T * dt, integrator="rk4")
    out = build_simulator(s).simulate({})
    np.testing.assert_allclose(out.joint_pos, Q, atol=1e-8)
    assert np.abs(Q[:, 0]).max() > 0.1


@pytest.mark.slow
def test_double_pendulum():
    """Two capsule links from 60 and -30 degrees. Chaos amplifies round-off by ~e^(lambda t): over
    3 s the angles agree within 1e-6 rad; beyond ~10 s comparison loses meaning."""
    dt, T = 1e-3, 3000
    body = ('<body><joint type="hinge" axis="0 1 0"/>'
            '<geom type="capsule" fromto="0 0 -0.02 0 0 -0.28" size="0.02" mass="0.5"/>'
            '<body pos="0 0 -0.3"><joint type="hinge" axis="0 1 0"/>'
            '<geom type="capsule" fromto="0 0 -0.02 0 0 -0.28" size="0.02" mass="0.5"/>'
            '</body></body>')
    th = [np.pi / 3, -np.pi / 6]
    Q, V, X, _ = rollout(xml(body, dt), T, qpos=th)
    from scenes import chain
    s = chain(2, link=0.3, mass=0.5, r=0.02, angles=th, dt=dt, duration=T * dt)
    out = build_simulator(s).simulate({})
    np.testing.assert_allclose(out.joint_pos, Q, atol=1e-6)


def test_spring_mass_damper_tendon():
    """Block on a vertical slide hanging from a spring + damper (MuJoCo spatial tendon)."""
    dt, T, k, l0, cd = 1e-3, 2000, 30.0, 0.9, 0.4
    body = ('<site name="anchor" pos="0 0 1.6"/>'
            '<body pos="0 0 0"><joint type="slide" axis="0 0 1"/>'
            '<geom type="box" size="0.05 0.05 0.05" mass="0.5"/><site name="hook" pos="0 0 0.05"/>'
            '</body>')
    tail = (f'<tendon><spatial stiffness="{k}" springlength="{l0}" damping="{cd}">'
            '<site site="anchor"/><site site="hook"/></spatial></tendon>')
    Q, V, X, _ = rollout(xml(body, dt, tail=tail), T)
    block = box("block", (0.1, 0.1, 0.1), 0.5, (0, 0, 0))
    j = Joint("guide", "slider", "world", "block", axis=c((0, 0, 1)))
    pr = dict(anchor=(0, 0, 1.6), attachment=(0, 0, 0.05))
    s = scene([block], [j], [gravity(), effect("spring", "block", stiffness=k, rest_length=l0, **pr),
                             effect("damper", "block", coefficient=cd, **pr)],
              dt=dt, duration=T * dt, integrator="rk4")
    out = build_simulator(s).simulate({})
    np.testing.assert_allclose(out.joint_pos[:, 0], Q[:, 0], atol=1e-9)
    assert np.ptp(Q[:, 0]) > 0.1


@pytest.mark.slow
def test_free_box_tumbling():
    """Torque-free asymmetric box spun near its unstable intermediate axis (gyroscopic bias terms):
    it flips within 1.5 s, which amplifies round-off; orientations agree within 1e-5."""
    dt, T = 1e-3, 1500
    w0 = np.array([0.05, 6.0, 0.1])  # body frame = world frame at t = 0
    quat0 = (0.9, 0.2, -0.1, 0.3)
    qn = np.array(quat0) / np.linalg.norm(quat0)
    body = ('<body><freejoint/><geom type="box" size="0.2 0.1 0.05" mass="2"/></body>')
    Q, V, X, R = rollout(xml(body, dt).replace('gravity="0 0 -9.81"', 'gravity="0 0 0"'), T,
        qpos=np.r_[0, 0, 1, qn], qvel=np.r_[0.3, 0, 0, w0])
    from physdsl.physics.spatial import quat_to_mat
    Rw = np.asarray(quat_to_mat(np.asarray(qn)))
    b = Body("box", Shape("box", {"size": c((0.4, 0.2, 0.1))}), mass=c(2.0),
             position=c((0, 0, 1)), orientation=c(tuple(qn)), velocity=c((0.3, 0, 0)),
             angular_velocity=c(tuple(Rw @ w0)))
    s = scene([b], dt=dt, duration=T * dt, integrator="rk4")
    out = build_simulator(s).simulate({})
    sign = np.sign(np.sum(out.body_quat[:, 0] * R[:, 1], -1))[:, None]
    np.testing.assert_allclose(out.body_quat[:, 0] * sign, R[:, 1], atol=1e-5)
    assert np.abs(R[:, 1] - R[0, 1]).max() > 0.5  # it really tumbles
    np.testing.assert_allclose(out.body_pos[:, 0], X[:, 1], atol=1e-10)
    # MuJoCo's free-joint angular velocity is in the body frame; ours is reported in world
    np.testing.assert_allclose(out.body_angvel[-1, 0], np.asarray(quat_to_mat(R[-1, 1])) @ V[-1, 3:],
                               atol=1e-4)
