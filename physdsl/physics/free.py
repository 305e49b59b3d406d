"""Fast path for scenes whose moving bodies are all free and unjointed (balls, thrown objects).

Such a scene needs no tree algorithms: each body obeys the Newton-Euler equations about its
centre of mass, vectorised over bodies with elementwise arithmetic (no tiny matrix products,
no per-body Python loop). Coordinates are those of the free joint (as MuJoCo): q = (origin
position, orientation quaternion), v = (world velocity of the origin, body-frame angular
velocity). Results equal the articulated-body algorithm's (tests compare them).
"""
from __future__ import annotations

import jax.numpy as jnp

from .kinematics import Kin
from .rows import place, take
from .spatial import mm, mtv, mv, normalize, quat_to_mat, skew
from .structure import PhysicsModel


def _place(model: PhysicsModel, static, moving):
    """Body-indexed array: ``moving`` rows for the free bodies, ``static`` rows elsewhere."""
    return place(static, model.free_bodies, moving)


def free_kinematics(model: PhysicsModel, prm: dict, q, v, with_jac: bool = False) -> Kin:
    """Poses and velocities of every body (static ones at their reference pose)."""
    nF, B = len(model.free_bodies), model.nbody
    fb = model.free_bodies
    qf, vf = q.reshape(nF, 7), v.reshape(nF, 6)
    x, qb = qf[:, :3], normalize(qf[:, 3:])
    R = quat_to_mat(qb)
    w = mv(R, vf[:, 3:])
    r = mv(R, take(prm["com"], fb))
    vcom = vf[:, :3] + jnp.cross(w, r)
    quat0 = normalize(prm["ref_quat"])
    rot0 = quat_to_mat(quat0)
    pos0 = prm["ref_pos"]
    zero = jnp.zeros((B, 3), q.dtype)
    jac = None
    if with_jac:
        # spatial Jacobian block of a free joint: omega = R w_l, v_O = v_x + x x (R w_l)
        top = jnp.concatenate([jnp.zeros((nF, 3, 3), q.dtype), R], 2)
        bot = jnp.concatenate([jnp.broadcast_to(jnp.eye(3, dtype=q.dtype), (nF, 3, 3)),
                               mm(skew(x), R)], 2)
        blocks = jnp.concatenate([top, bot], 1)  # (nF, 6, 6)
        full = jnp.einsum("fij,fg->figj", blocks, jnp.eye(nF, dtype=q.dtype)).reshape(nF, 6, 6 * nF)
        jac = _place(model, jnp.zeros((B, 6, 6 * nF), q.dtype), full)
    return Kin(pos=_place(model, pos0, x), quat=_place(model, quat0, qb),
               rot=_place(model, rot0, R), com=_place(model, pos0 + mv(rot0, prm["com"]), x + r),
               ang=_place(model, zero, w), vcom=_place(model, zero, vcom), q=q, v=v, jac=jac)


def free_accel(model: PhysicsModel, prm: dict, kin: Kin, force, torque, tau):
    """dv/dt of every free body from world forces at the COMs, world torques (B, 3) and
    generalized forces tau (nv,) (the free-joint components: origin force, body-frame torque
    about the origin)."""
    nF = len(model.free_bodies)
    fb = model.free_bodies
    R, x, r = take(kin.rot, fb), take(kin.pos, fb), take(kin.com, fb) - take(kin.pos, fb)
    tg = tau.reshape(nF, 6)
    F = take(force, fb) + tg[:, :3]
    T = take(torque, fb) + mv(R, tg[:, 3:]) - jnp.cross(r, tg[:, :3])
    wl = kin.v.reshape(nF, 6)[:, 3:]
    Ib = take(prm["inertia"], fb)
    dwl = mv(prm["free_inv_inertia"], mtv(R, T) - jnp.cross(wl, mv(Ib, wl)))
    w, dw = take(kin.ang, fb), mv(R, dwl)
    a = F / take(prm["mass"], fb)[:, None] - jnp.cross(dw, r) - jnp.cross(w, jnp.cross(w, r))
    return jnp.concatenate([a, dwl], -1).reshape(-1)


def free_mass_matrix(model: PhysicsModel, prm: dict, kin: Kin):
    """Block-diagonal M (nv, nv): KE = m/2 |v_x + A w_l|^2 + w_l.I w_l/2, A = -R skew(c)."""
    nF = len(model.free_bodies)
    fb = model.free_bodies
    m, R, C = take(prm["mass"], fb), take(kin.rot, fb), skew(take(prm["com"], fb))
    A = -mm(R, C)
    eye = jnp.broadcast_to(jnp.eye(3, dtype=R.dtype), (nF, 3, 3))
    top = jnp.concatenate([m[:, None, None] * eye, m[:, None, None] * A], 2)
    bot = jnp.concatenate([m[:, None, None] * jnp.swapaxes(A, 1, 2),
                           m[:, None, None] * mm(jnp.swapaxes(C, 1, 2), C) + take(prm["inertia"], fb)], 2)
    blocks = jnp.concatenate([top, bot], 1)
    return jnp.einsum("fij,fg->figj", blocks, jnp.eye(nF, dtype=R.dtype)).reshape(6 * nF, 6 * nF)


def free_inverse_inertia(model: PhysicsModel, inertia):
    """Inverse body-frame inertias (nF, 3, 3) of the free bodies (computed once per rollout).

    By cofactors (rows a, b, c: inverse = [b x c, c x a, a x b]^T / det): a few elementwise
    operations, where ``jnp.linalg.inv`` traces and compiles an LU factorisation and solves.
    """
    m = take(inertia, model.free_bodies)
    a, b, c = m[:, 0], m[:, 1], m[:, 2]
    cof = jnp.stack([jnp.cross(b, c), jnp.cross(c, a), jnp.cross(a, b)], axis=-1)
    det = jnp.sum(a * cof[:, :, 0], axis=-1)
    return cof / det[:, None, None]
