"""Rigid-body dynamics in world coordinates: the joint-space mass matrix and bias forces from the
body Jacobians (vectorised over bodies), and Featherstone's articulated-body algorithm (loops over
the static tree at trace time) for trees too large for physics/tree.py's one Cholesky solve.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from .kinematics import Kin
from .spatial import cross_force, mm, mv
from .structure import PhysicsModel


def generalized_forces(model: PhysicsModel, kin: Kin, load):
    """tau (nv,) of a Load: joint forces plus J^T of each body's spatial force at the origin."""
    n_origin = load.torque + jnp.cross(kin.com, load.force)
    f = jnp.concatenate([n_origin, load.force], -1)
    return load.joint + jnp.sum(kin.jac * f[..., None], axis=(0, 1))


def mass_matrix(model: PhysicsModel, kin: Kin):
    """Joint-space mass matrix M = sum_b J_b^T I_b J_b (nv, nv), vectorised over bodies."""
    IJ = mm(kin.inertia, kin.jac)  # (B, 6, nv)
    return jnp.sum(kin.jac[..., :, None] * IJ[..., None, :], axis=(0, 1))


def bias_forces(model: PhysicsModel, kin: Kin):
    """Coriolis and centrifugal generalized forces C(q, v) v: J^T of each body's inertial force
    at zero joint acceleration, I a0 + v x* I v (Newton-Euler in Jacobian form)."""
    I, vel = kin.inertia, kin.vel
    f = mv(I, kin.acc0) + cross_force(vel, mv(I, vel))
    return jnp.sum(kin.jac * f[..., None], axis=(0, 1))


def inverse_dynamics(model: PhysicsModel, kin: Kin, qdd):
    """Generalized forces tau = M qdd + bias (no external forces)."""
    return mv(mass_matrix(model, kin), qdd) + bias_forces(model, kin)


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


def forward_dynamics(model: PhysicsModel, kin: Kin, tau):
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
