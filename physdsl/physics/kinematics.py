"""Forward kinematics over the tree: body poses, spatial velocities, motion subspaces, Jacobians.

Each body's pose is ``D_i`` (the rigid motion taking its reference pose to its current pose)
applied to its reference pose, with D_i = D_parent o J_i(q_i) and J_i the joint's motion at
the reference configuration. Motion subspaces S_i (6 x nv_i) are world-frame at the origin.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .structure import PhysicsModel
from .spatial import (cross_motion, mm, mv, normalize, quat_axis_angle, quat_conj, quat_exp,
                      quat_mul, quat_to_mat, skew, spatial_inertia)


class Kin(NamedTuple):
    """Kinematics at one state. The first eight fields exist for every scene; the tree fields
    (spatial velocities, Jacobians, inertias, motion subspaces) are None on the free-body path
    (``free_kinematics``), where ``jac`` is filled only when contacts need it."""

    pos: jnp.ndarray  # (B, 3) body frame origins, world
    quat: jnp.ndarray  # (B, 4) body -> world
    rot: jnp.ndarray  # (B, 3, 3)
    com: jnp.ndarray  # (B, 3) centres of mass, world
    ang: jnp.ndarray  # (B, 3) world angular velocities
    vcom: jnp.ndarray  # (B, 3) world velocities of the centres of mass
    q: jnp.ndarray
    v: jnp.ndarray
    vel: jnp.ndarray | None = None  # (B, 6) spatial velocities (omega, v_O)
    jac: jnp.ndarray | None = None  # (B, 6, nv) spatial Jacobians: vel[i] = jac[i] @ v
    bias_acc: jnp.ndarray | None = None  # (B, 6) c_i = dS_i/dt qdot_i
    inertia: jnp.ndarray | None = None  # (B, 6, 6) spatial inertias at the origin
    S: tuple | None = None  # per body (6, nv_i) motion subspace
    acc0: jnp.ndarray | None = None  # (B, 6) spatial accelerations at zero joint acceleration
    core: "Kin | None" = None  # the core model's, where welds are merged (``welds``)


BARRIER_DEPTH = 3


def _barrier(model: PhysicsModel, x):
    """An optimization barrier in deep trees only: it stops XLA from fusing (and recomputing)
    whole ancestor chains per body, but in shallow trees it only splits kernels."""
    if max(_depths(model)) < BARRIER_DEPTH:
        return x
    return jax.lax.optimization_barrier(x)


def _depths(model: PhysicsModel):
    d = [0] * model.nbody
    for i in model.order:
        p = model.joints[i].parent
        d[i] = d[p] + 1 if p >= 0 else 1
    return d or [0]


def _joint_motion(tj, prm: dict, i: int, qi, parent, dtype):
    """Joint i's motion D_i = D_parent o J_i(q_i) as (quaternion, translation), its world motion
    subspace S_i, and D_i's rotation matrix where it is at hand (else None). ``parent`` is the
    parent's (quaternion, translation, rotation matrix), or None for the world: its identity
    motion is then traced as no operations at all (the same numbers: x * 1 + 0 = x)."""
    on_parent = (lambda x: x) if parent is None else (lambda x: mv(parent[2], x))  # noqa: E731
    then = (lambda q_: q_) if parent is None else (lambda q_: quat_mul(parent[0], q_))  # noqa: E731
    shift = (lambda t: t) if parent is None else (lambda t: t + parent[1])  # noqa: E731
    ref_p, ref_q = prm["ref_pos"][i], prm["ref_quat"][i]
    q_p, t_p = (jnp.array([1.0, 0.0, 0.0, 0.0], dtype=dtype), jnp.zeros(3, dtype=dtype)) \
        if parent is None else parent[:2]
    R_D = None
    if tj.kind == "fixed":
        qD, tD = q_p, t_p
        Si = jnp.zeros((6, 0), dtype=dtype)
    elif tj.kind == "hinge":
        a, p = prm["axis"][i], prm["anchor"][i]
        qJ = quat_axis_angle(a, qi[0])
        R_J = quat_to_mat(qJ)
        qD = then(qJ)
        R_D = R_J if parent is None else None  # the world's child turns by its joint alone
        tD = shift(on_parent(p - mv(R_J, p)))
        a_w, p_w = on_parent(a), shift(on_parent(p))
        Si = jnp.concatenate([a_w, jnp.cross(p_w, a_w)])[:, None]
    elif tj.kind == "slider":
        a_w = on_parent(prm["axis"][i])
        qD, tD = q_p, shift(a_w * qi[0])
        Si = jnp.concatenate([jnp.zeros(3, dtype=dtype), a_w])[:, None]
    elif tj.kind == "ball":
        p = prm["anchor"][i]
        qQ = normalize(qi)
        RQ = quat_to_mat(qQ)
        qD = then(qQ)
        tD = shift(on_parent(p - mv(RQ, p)))
        E = RQ if parent is None else mm(parent[2], RQ)
        Si = jnp.concatenate([E, mm(skew(shift(on_parent(p))), E)], 0)
    elif tj.kind == "free":
        x, qb = qi[:3], normalize(qi[3:])
        R = quat_to_mat(qb)
        qD = quat_mul(qb, quat_conj(ref_q))
        tD = x - mv(quat_to_mat(qD), ref_p)
        St = jnp.concatenate([jnp.zeros((3, 3), dtype=dtype), jnp.eye(3, dtype=dtype)], 0)
        Sr = jnp.concatenate([R, mm(skew(x), R)], 0)
        Si = jnp.concatenate([St, Sr], 1)
    else:  # pragma: no cover - model.py rejects other kinds
        raise ValueError(tj.kind)
    return qD, tD, Si, R_D


def forward_kinematics(model: PhysicsModel, prm: dict, q, v) -> Kin:
    """Poses, velocities, Jacobians and spatial inertias of every body at state (q, v)."""
    B, nv = model.nbody, model.nv
    dtype = q.dtype if q.size else prm["ref_pos"].dtype
    D, pos, quat, vel, jac, cacc, acc0, S = ([None] * B for _ in range(8))  # per body
    zero6 = jnp.zeros(6, dtype=dtype)
    for i in model.order:
        tj = model.joints[i]
        root = tj.parent < 0
        parent = None if root else (*D[tj.parent], quat_to_mat(D[tj.parent][0]))
        v_p = zero6 if root else vel[tj.parent]
        J_p = jnp.zeros((6, nv), dtype=dtype) if root else jac[tj.parent]
        qi = q[tj.qadr:tj.qadr + tj.nq]
        vi = v[tj.vadr:tj.vadr + tj.nv]
        qD, tD, Si, R_D = _joint_motion(tj, prm, i, qi, parent, dtype)
        qD, tD = _barrier(model, (qD, tD))
        D[i] = (qD, tD)
        quat[i] = normalize(quat_mul(qD, prm["ref_quat"][i]))
        pos[i] = mv(quat_to_mat(qD) if R_D is None else R_D, prm["ref_pos"][i]) + tD
        vel[i] = v_p + (mv(Si, vi) if tj.nv else zero6)
        c = zero6
        if tj.kind == "free":
            c = cross_motion(vel[i], mv(Si[:, 3:], vi[3:])) + cross_motion(v_p, mv(Si[:, :3], vi[:3]))
        elif tj.nv:
            c = cross_motion(v_p, mv(Si, vi))
        cacc[i] = c
        acc0[i] = (zero6 if root else acc0[tj.parent]) + c
        S[i] = Si
        vel[i], Si = _barrier(model, (vel[i], Si))
        jac[i] = J_p.at[:, tj.vadr:tj.vadr + tj.nv].set(Si) if tj.nv else J_p
    pos_a, quat_a = jnp.stack(pos), jnp.stack(quat)
    rot = quat_to_mat(quat_a)
    com = pos_a + mv(rot, prm["com"])
    I_world = mm(mm(rot, prm["inertia"]), jnp.swapaxes(rot, -1, -2))
    inertia6 = spatial_inertia(prm["mass"], I_world, com)
    vel_a = jnp.stack(vel)
    ang = vel_a[:, :3]
    vcom = vel_a[:, 3:] + jnp.cross(ang, com)
    return Kin(pos_a, quat_a, rot, com, ang, vcom, q, v, vel_a, jnp.stack(jac), jnp.stack(cacc),
               inertia6, tuple(S), jnp.stack(acc0))


def point_velocity(kin: Kin, body: int, point):
    """World velocity of the body-fixed point currently at ``point``."""
    return kin.vcom[body] + jnp.cross(kin.ang[body], point - kin.com[body])


def integrate_q(model: PhysicsModel, q, v, h):
    """q advanced by velocity v over time h, every joint at once: hinge and slider coordinates
    by q + h v, quaternions (ball, a free joint's rotation) on the manifold, renormalised."""
    lin_q, lin_v, quat_q, quat_v = _position_tables(model)
    if not len(quat_q) and np.array_equal(lin_q, np.arange(q.shape[0])):
        return q + h * (v if np.array_equal(lin_v, np.arange(v.shape[0])) else v[lin_v])
    out = q.at[lin_q].add(h * v[lin_v]) if len(lin_q) else q
    if len(quat_q):
        qq = q[quat_q]
        out = out.at[quat_q].set(normalize(quat_mul(qq, quat_exp(v[quat_v] * h))))
    return out


def _position_tables(model: PhysicsModel):
    """Static indices: q and v of every coordinate advanced linearly; (n, 4) q and (n, 3) v of
    every quaternion."""
    lin_q, lin_v, quat_q, quat_v = [], [], [], []
    for j in model.joints:
        if j.kind in ("hinge", "slider"):
            lin_q.append(j.qadr), lin_v.append(j.vadr)
        elif j.kind == "free":
            lin_q += range(j.qadr, j.qadr + 3)
            lin_v += range(j.vadr, j.vadr + 3)
            quat_q.append(range(j.qadr + 3, j.qadr + 7)), quat_v.append(range(j.vadr + 3, j.vadr + 6))
        elif j.kind == "ball":
            quat_q.append(range(j.qadr, j.qadr + 4)), quat_v.append(range(j.vadr, j.vadr + 3))
    return (np.array(lin_q, int), np.array(lin_v, int), np.array(quat_q, int).reshape(-1, 4),
            np.array(quat_v, int).reshape(-1, 3))
