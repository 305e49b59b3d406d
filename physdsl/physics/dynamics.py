"""Rigid-body dynamics in world coordinates (Featherstone): CRBA mass matrix, RNEA bias forces,
ABA forward dynamics. All loops run over the static tree at trace time.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from .kinematics import Kin
from .model import Model
from .spatial import cross_force


def generalized_forces(model: Model, kin: Kin, load):
    """tau (nv,) of a Load: joint forces plus J^T of each body's spatial force at the origin."""
    n_origin = load.torque + jnp.cross(kin.com, load.force)
    f = jnp.concatenate([n_origin, load.force], -1)
    return load.joint + jnp.einsum("bkn,bk->n", kin.jac, f)


def mass_matrix(model: Model, kin: Kin):
    """Joint-space mass matrix M (nv, nv) by the composite-rigid-body algorithm."""
    nv = model.nv
    Ic = [kin.inertia[i] for i in range(model.nbody)]
    for i in reversed(model.order):
        p = model.joints[i].parent
        if p >= 0:
            Ic[p] = Ic[p] + Ic[i]
    M = jnp.zeros((nv, nv), dtype=kin.inertia.dtype)
    for i in model.order:
        tj = model.joints[i]
        if not tj.nv:
            continue
        F = Ic[i] @ kin.S[i]
        si = slice(tj.vadr, tj.vadr + tj.nv)
        M = M.at[si, si].set(kin.S[i].T @ F)
        j = tj.parent
        while j >= 0:
            tp = model.joints[j]
            if tp.nv:
                sj = slice(tp.vadr, tp.vadr + tp.nv)
                blk = kin.S[j].T @ F
                M = M.at[sj, si].set(blk).at[si, sj].set(blk.T)
            j = tp.parent
    return M


def inverse_dynamics(model: Model, kin: Kin, qdd):
    """Generalized forces tau = M qdd + bias (recursive Newton-Euler, no external forces)."""
    B = model.nbody
    a: list = [None] * B
    f: list = [None] * B
    zero6 = jnp.zeros(6, dtype=kin.vel.dtype)
    for i in model.order:
        tj = model.joints[i]
        ap = a[tj.parent] if tj.parent >= 0 else zero6
        ai = ap + kin.bias_acc[i]
        if tj.nv:
            ai = ai + kin.S[i] @ qdd[tj.vadr:tj.vadr + tj.nv]
        a[i] = ai
        I, vi = kin.inertia[i], kin.vel[i]
        f[i] = I @ ai + cross_force(vi, I @ vi)
    tau = jnp.zeros(model.nv, dtype=kin.vel.dtype)
    for i in reversed(model.order):
        tj = model.joints[i]
        if tj.nv:
            tau = tau.at[tj.vadr:tj.vadr + tj.nv].set(kin.S[i].T @ f[i])
        if tj.parent >= 0:
            f[tj.parent] = f[tj.parent] + f[i]
    return tau


def bias_forces(model: Model, kin: Kin):
    """Coriolis and centrifugal generalized forces C(q, v) v (RNEA with zero acceleration)."""
    return inverse_dynamics(model, kin, jnp.zeros(model.nv, dtype=kin.vel.dtype))


def small_inv(D):
    """Inverse of a small SPD joint-space matrix: closed form for 1x1 and 3x3 (cheap to compile)."""
    n = D.shape[0]
    if n == 1:
        return 1.0 / D
    if n == 3:
        a, b, c = D[0], D[1], D[2]
        adj = jnp.stack([jnp.cross(b, c), jnp.cross(c, a), jnp.cross(a, b)], 1)
        return adj / jnp.dot(a, jnp.cross(b, c))
    return jnp.linalg.inv(D)


def forward_dynamics(model: Model, kin: Kin, tau):
    """Joint accelerations qdd = M^-1 (tau - bias) by the articulated-body algorithm, O(n)."""
    B = model.nbody
    IA = [kin.inertia[i] for i in range(B)]
    pA = [cross_force(kin.vel[i], kin.inertia[i] @ kin.vel[i]) for i in range(B)]
    U: list = [None] * B
    Dinv: list = [None] * B
    u: list = [None] * B
    for i in reversed(model.order):
        tj = model.joints[i]
        Ia, pa = IA[i], pA[i]
        c = kin.bias_acc[i]
        if tj.nv:
            S = kin.S[i]
            U[i] = Ia @ S
            D = S.T @ U[i]
            Dinv[i] = small_inv(D)
            u[i] = tau[tj.vadr:tj.vadr + tj.nv] - S.T @ pa
            Ia = Ia - U[i] @ Dinv[i] @ U[i].T
            pa = pa + Ia @ c + U[i] @ (Dinv[i] @ u[i])
        else:
            pa = pa + Ia @ c
        if tj.parent >= 0:
            IA[tj.parent], pA[tj.parent] = jax.lax.optimization_barrier(
                (IA[tj.parent] + Ia, pA[tj.parent] + pa))
    a: list = [None] * B
    qdd = jnp.zeros(model.nv, dtype=kin.vel.dtype)
    zero6 = jnp.zeros(6, dtype=kin.vel.dtype)
    for i in model.order:
        tj = model.joints[i]
        ap = (a[tj.parent] if tj.parent >= 0 else zero6) + kin.bias_acc[i]
        if tj.nv:
            qi = Dinv[i] @ (u[i] - U[i].T @ ap)
            qdd = qdd.at[tj.vadr:tj.vadr + tj.nv].set(qi)
            ap = ap + kin.S[i] @ qi
        a[i] = jax.lax.optimization_barrier(ap)
    return qdd
