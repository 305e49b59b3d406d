"""Free bodies under central forces: translation and rotation as two independent ODEs.

When a scene's moving bodies are all free, no contact can arise, each centre of mass is its
body's frame origin (primitive shapes) and every force-stage effect is central
(``Effect.central``: a force at the COM, no torque, reading only the COMs' positions and
velocities), the Newton-Euler equations split: m x'' = F(x, x', t) and Euler's torque-free
I w' = -w x I w (body frame), with the orientation carried along by w. Each part is integrated
alone with the very arithmetic of the coupled step (``integrate.step`` / ``_rk4``) minus its
terms that are exactly zero here (COM offsets, torques, the rotation of zero vectors), so the
states agree to rounding; the translation step is a handful of operations instead of the free
path's hundreds, and a likelihood that reads positions only never runs the rotation (the
simulator scans each part on its own, and XLA drops a scan whose results nobody reads).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .effects import EFFECTS
from .integrate import State, applied_load
from .kinematics import Kin
from .rows import place, take
from .spatial import mv, quat_integrate
from .structure import PhysicsModel


def decoupled(model: PhysicsModel) -> bool:
    """Whether ``model``'s free bodies translate and rotate independently (static)."""
    if model.free_bodies is None or model.ncon:
        return False
    if any(model.shape_kinds[b] == "mesh" for b in model.free_bodies):  # COM off the origin
        return False
    return all(EFFECTS[s.effect].central for s in model.sites if EFFECTS[s.effect].stage == "force")


class Translation(NamedTuple):
    x: jnp.ndarray  # (nF, 3) positions of the origins (= COMs)
    v: jnp.ndarray  # (nF, 3) their world velocities


class Rotation(NamedTuple):
    quat: jnp.ndarray  # (nF, 4) orientations (w, x, y, z)
    w: jnp.ndarray  # (nF, 3) body-frame angular velocities


def split(model: PhysicsModel, q, v) -> tuple[Translation, Rotation]:
    """The free-joint coordinates q (..., nq), v (..., nv) as their two parts."""
    nF = len(model.free_bodies)
    qf, vf = q.reshape(*q.shape[:-1], nF, 7), v.reshape(*v.shape[:-1], nF, 6)
    return (Translation(qf[..., :3], vf[..., :3]), Rotation(qf[..., 3:], vf[..., 3:]))


def join(tr: Translation, rot: Rotation):
    """Inverse of ``split``: (q (..., nq), v (..., nv))."""
    q = jnp.concatenate([tr.x, rot.quat], -1)
    v = jnp.concatenate([tr.v, rot.w], -1)
    return q.reshape(*q.shape[:-2], -1), v.reshape(*v.shape[:-2], -1)


class Frame(NamedTuple):
    """Rows of the bodies that do not move (computed once per rollout)."""

    pos: jnp.ndarray  # (B, 3) reference origins
    com: jnp.ndarray  # (B, 3) reference COMs
    zero: jnp.ndarray  # (B, 3)


def frame(model: PhysicsModel, prm: dict) -> Frame | None:
    """The static rows, or None when every body moves (``place`` then reads no row of them)."""
    if tuple(model.free_bodies) == tuple(range(model.nbody)):
        return None
    pos0 = prm["ref_pos"]
    com0 = pos0 + mv(prm["ref_rot"], prm["com"])
    return Frame(pos0, com0, jnp.zeros_like(pos0))


def _translation_accel(model: PhysicsModel, prm: dict, fr: Frame | None, x, v, t, t_step):
    """(nF, 3) accelerations of the free bodies: summed central forces over mass."""
    fb = model.free_bodies
    if fr is None:  # every body moves: its rows are all there is
        kin = Kin(pos=x, quat=None, rot=None, com=x, ang=None, vcom=v, q=None, v=None)
    else:
        kin = Kin(pos=place(fr.pos, fb, x), quat=None, rot=None, com=place(fr.com, fb, x),
                  ang=None, vcom=place(fr.zero, fb, v), q=None, v=None)
    empty = jnp.zeros(0, x.dtype)
    load = applied_load(model, prm, kin, State(empty, empty, empty, jnp.zeros((0, 3), x.dtype)),
                        t, t_step)
    return take(load.force, fb) / take(prm["mass"], fb)[:, None]


def _rotation_accel(model: PhysicsModel, prm: dict, w):
    """(nF, 3) body-frame angular accelerations without torque: I^-1 (-w x I w)."""
    inertia = take(prm["inertia"], model.free_bodies)
    return mv(prm["free_inv_inertia"], -jnp.cross(w, mv(inertia, w)))


def translation_step(model: PhysicsModel, prm: dict, fr: Frame | None, s: Translation, t,
                     h) -> Translation:
    """Advance the translation by h from time t with the scene's integrator."""
    acc = lambda x, v, tt: _translation_accel(model, prm, fr, x, v, tt, t)  # noqa: E731
    x, v = s
    if model.integrator != "rk4":  # semi-implicit Euler
        v_next = v + h * acc(x, v, t)
        return Translation(x + h * v_next, v_next)
    a1 = acc(x, v, t)
    v2 = v + 0.5 * h * a1
    a2 = acc(x + (0.5 * h) * v, v2, t + 0.5 * h)
    v3 = v + 0.5 * h * a2
    a3 = acc(x + (0.5 * h) * v2, v3, t + 0.5 * h)
    v4 = v + h * a3
    a4 = acc(x + h * v3, v4, t + h)
    v_avg = (v + 2.0 * v2 + 2.0 * v3 + v4) / 6.0
    a_avg = (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
    return Translation(x + h * v_avg, v + h * a_avg)


def rotation_step(model: PhysicsModel, prm: dict, s: Rotation, h) -> Rotation:
    """Advance the torque-free rotation by h with the scene's integrator."""
    acc = lambda w: _rotation_accel(model, prm, w)  # noqa: E731
    quat, w = s
    advance = jax.vmap(lambda qi, wi: quat_integrate(qi, wi, h))
    if model.integrator != "rk4":
        w_next = w + h * acc(w)
        return Rotation(advance(quat, w_next), w_next)
    b1 = acc(w)
    w2 = w + 0.5 * h * b1
    b2 = acc(w2)
    w3 = w + 0.5 * h * b2
    b3 = acc(w3)
    w4 = w + h * b3
    b4 = acc(w4)
    w_avg = (w + 2.0 * w2 + 2.0 * w3 + w4) / 6.0
    b_avg = (b1 + 2.0 * b2 + 2.0 * b3 + b4) / 6.0
    return Rotation(advance(quat, w_avg), w + h * b_avg)
