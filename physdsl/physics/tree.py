"""Trees of hinges and sliders (and welds) without a Python loop per body: kinematics and dynamics
as a fixed handful of vectorised array operations, whatever the number of bodies.

Each body's motion D_i = D_parent o J_i(q_i) is composed over its ancestors by pointer jumping
(ceil(log2 depth) rounds of one batched composition each, the rotation matrix carried beside
the quaternion so no round converts one into the other). World joint axes and anchors follow
from D_i alone (a hinge's axis and anchor are fixed by its own motion), spatial velocities,
bias accelerations and Jacobians from the static ancestor matrix A (A[i, j] = 1 where j is i or
an ancestor of i) by one product each, the joint-space mass matrix from the composite inertias
A^T I (CRBA: M[j, k] = S_j . Ic_k S_k where j's body is an ancestor of k's), forces on the
dofs from the subtree sums A^T f. Where XLA CPU runs a loop as a call per operation, a step's
cost is its number of operations, not its flops, so this beats the recursive algorithms (Python
loops over the static tree, an operation or more per body) at the sizes of scenes; where the
loop is one kernel (``xla_flags``) flops count, and trees of a few dofs take the recursive
algorithms instead (``applies``; measured: ``benchmarks/physics.py``).
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax.scipy.linalg import cho_factor, cho_solve

from .. import xla_flags
from .dense import spd_solve
from .kinematics import Kin
from .spatial import (cross_force, mm, mv, normalize, quat_axis_angle, quat_mul,
                      quat_to_mat, skew, spatial_inertia)
from .structure import PhysicsModel

# above this many dofs the articulated-body algorithm (``dynamics.forward_dynamics``): the
# Cholesky solve here is O(nv^3)
TREE_MAX = 64
# ``static_mm``: products with more multiply-adds than this as dots
FUSED_MM_MAX = 4096


# at most this many dofs, a contact-free tree whose rollout loop runs as one kernel
# (``xla_flags``) takes the recursive algorithms: with no cost per operation their fewer flops
# win (side by side, us/step: pendulum case 4.36 -> 1.66, cart-pole 8.28 -> 2.17, chain5
# 4.66 -> 2.11); above it their compile grows too fast: a fit's Gauss-Newton program (forward
# mode through an RK4 rollout of 3 000 steps, first call) of a hinge chain, recursive / here,
# 2 links 31.5 / 19.1 s, 3 links 63.0 / 32.4 s, 4 links 117-124 / 38 s, while a call costs
# 38 / 34, 58 / 79-112, 61-81 / 135-153 ms: a refit compiles once and calls it a few dozen times
RECURSIVE_MAX = 2


def applies(model: PhysicsModel) -> bool:
    """A jointed tree small enough for the vectorised path (free-body scenes have their own),
    and not one the recursive algorithms run faster (``RECURSIVE_MAX``)."""
    if model.nbody == 0 or model.nv > TREE_MAX:
        return False
    return not (model.ncon == 0 and model.nv <= RECURSIVE_MAX and xla_flags.in_effect())


def _tables(model: PhysicsModel):
    """Static index tables: parent (B,) with -1 -> B (a zero row), ancestor matrix A (B, B),
    body and column of each dof (nv,), each body's dof per column (B, K) (nv: none), jumping
    rounds (per round, each body's ancestor that many levels up, -1: none)."""
    B, nv = model.nbody, model.nv
    parent = np.array([j.parent for j in model.joints])
    A = np.eye(B)
    for i in model.order:
        if parent[i] >= 0:
            A[i] = np.maximum(A[i], A[parent[i]])
    K = max([j.nv for j in model.joints] + [1])
    dof_body, dof_col = np.zeros(nv, int), np.zeros(nv, int)
    vidx = np.full((B, K), nv)
    for j in model.joints:
        dof_body[j.vadr:j.vadr + j.nv] = j.body
        dof_col[j.vadr:j.vadr + j.nv] = np.arange(j.nv)
        vidx[j.body, :j.nv] = np.arange(j.vadr, j.vadr + j.nv)
    rounds, anc = [], parent.copy()
    while (anc >= 0).any():
        rounds.append(anc.copy())
        anc = np.where(anc >= 0, anc[np.maximum(anc, 0)], -1)
    return np.where(parent >= 0, parent, B), A, dof_body, dof_col, vidx, rounds


def _compose(outer, inner):
    """``outer`` o ``inner`` of rigid motions packed as (..., 16) rows [quaternion (4), rotation
    matrix (9, row-major), translation (3)]: the matrix rides along, so a round of pointer
    jumping is one gather and one elementwise kernel, with no quaternion-to-matrix conversion."""
    B = outer.shape[:-1]
    Ra, Rb = outer[..., 4:13].reshape(B + (3, 3)), inner[..., 4:13].reshape(B + (3, 3))
    q = quat_mul(outer[..., :4], inner[..., :4])
    R = mm(Ra, Rb).reshape(B + (9,))
    t = mv(Ra, inner[..., 13:]) + outer[..., 13:]
    return jnp.concatenate([q, R, t], -1)


def _mask(model: PhysicsModel, *kinds):
    return np.array([j.kind in kinds for j in model.joints])


def _kinds(model: PhysicsModel) -> frozenset:
    """The joint kinds present: only their formulas are traced (a hinge chain pays for no ball or
    free joint's quaternion algebra: fewer kernels per step, a smaller program to compile)."""
    return frozenset(j.kind for j in model.joints)


def _joint_motions(model: PhysicsModel, prm: dict, q):
    """Each body's joint motion J_i(q_i) (a free joint: its whole motion) as (quaternion (B, 4),
    rotation matrix (B, 3, 3), translation (B, 3)); also the ball and free joints' own
    quaternions and a free joint's position (identity and zero where there is none)."""
    nq = model.nq
    kinds = _kinds(model)
    qx = jnp.concatenate([q, jnp.zeros(1, q.dtype)])
    hinge, slider = _mask(model, "hinge")[:, None], _mask(model, "slider")[:, None]
    ball, free = _mask(model, "ball")[:, None], _mask(model, "free")[:, None]
    a, p, ref_q = prm["axis"], prm["anchor"], prm["ref_quat"]
    ident = jnp.broadcast_to(jnp.array([1.0, 0.0, 0.0, 0.0], ref_q.dtype), ref_q.shape)
    x = jnp.zeros_like(prm["ref_pos"])
    qb = qJ = ident
    if kinds & {"hinge", "slider"}:
        one = np.array([j.qadr if j.kind in ("hinge", "slider") else nq for j in model.joints])
        th = qx[one]
    if kinds & {"ball", "free"}:
        quat_at = {"ball": 0, "free": 3}
        q4 = np.array([[j.qadr + quat_at[j.kind] + k if j.kind in quat_at else nq
                        for k in range(4)] for j in model.joints])
        qb = normalize(jnp.where(ball | free, qx[q4], ident))
        qJ = jnp.where(ball, qb, qJ)
    if "hinge" in kinds:
        qJ = jnp.where(hinge, quat_axis_angle(a, th), qJ)
    if "free" in kinds:
        x3 = np.array([[j.qadr + k if j.kind == "free" else nq for k in range(3)]
                       for j in model.joints])
        x = qx[x3]
        qJ = jnp.where(free, quat_mul(qb, ref_q * jnp.array([1.0, -1.0, -1.0, -1.0], q.dtype)), qJ)
    if "hinge" in kinds and kinds <= {"hinge", "slider", "fixed"}:
        # Rodrigues' formula: no quaternion-to-matrix conversion (fewer kernels per step)
        angle = jnp.where(hinge[:, 0], th, 0.0)
        c, s = jnp.cos(angle), jnp.sin(angle)
        aa = a[:, :, None] * a[:, None, :]
        RJ = (c[:, None, None] * jnp.eye(3, dtype=q.dtype) + s[:, None, None] * skew(a)
              + (1.0 - c)[:, None, None] * aa)
    else:
        RJ = quat_to_mat(qJ)
    tJ = jnp.zeros_like(x)
    if kinds & {"hinge", "ball"}:
        tJ = jnp.where(hinge | ball, p - mv(RJ, p), 0.0)
    if "slider" in kinds:
        tJ = tJ + jnp.where(slider, a * th[:, None], 0.0)
    if "free" in kinds:
        tJ = jnp.where(free, x - mv(RJ, prm["ref_pos"]), tJ)
    return qJ, RJ, tJ, qb, x


def _subspaces(model: PhysicsModel, prm: dict, R, tD, qb, x):
    """Motion subspaces (B, 6, K) in the world at the origin, and which columns turn with the
    body itself (a free joint's rotation) rather than with the parent; only the kinds present
    are traced (``_kinds``)."""
    K = max([j.nv for j in model.joints] + [1])
    kinds = _kinds(model)
    a_w, p_w = mv(R, prm["axis"]), mv(R, prm["anchor"]) + tD  # fixed by the joint's own motion
    cols = [jnp.zeros((model.nbody, 6), R.dtype) for _ in range(K)]
    if "hinge" in kinds:
        hinge = jnp.concatenate([a_w, jnp.cross(p_w, a_w)], -1)
        cols[0] = cols[0] + jnp.where(_mask(model, "hinge")[:, None], hinge, 0.0)
    if "slider" in kinds:
        slider = jnp.concatenate([jnp.zeros_like(a_w), a_w], -1)
        cols[0] = cols[0] + jnp.where(_mask(model, "slider")[:, None], slider, 0.0)
    if "ball" in kinds:
        E = R  # a ball joint's columns: the body's (D's) axes
        ball = jnp.concatenate([E, jnp.cross(p_w[:, :, None], E, axis=1)], 1)  # (B, 6, 3)
        for k in range(3):
            cols[k] = cols[k] + jnp.where(_mask(model, "ball")[:, None], ball[:, :, k], 0.0)
    if "free" in kinds:
        Rb = quat_to_mat(qb)
        eye = jnp.broadcast_to(jnp.eye(3, dtype=R.dtype), R.shape)
        free_t = jnp.concatenate([jnp.zeros_like(eye), eye], 1)
        free_r = jnp.concatenate([Rb, jnp.cross(x[:, :, None], Rb, axis=1)], 1)
        for k in range(K):
            fc = free_t[:, :, k] if k < 3 else free_r[:, :, k - 3]
            cols[k] = cols[k] + jnp.where(_mask(model, "free")[:, None], fc, 0.0)
    own = np.array([[j.kind == "free" and k >= 3 for k in range(K)] for j in model.joints])
    return jnp.stack(cols, -1), own


def tree_kinematics(model: PhysicsModel, prm: dict, q, v) -> Kin:
    """Poses, spatial velocities, Jacobians and inertias of every body at (q, v), vectorised."""
    B = model.nbody
    par, A, dof_body, dof_col, vidx, rounds = _tables(model)
    qJ, RJ, tJ, qb, x = _joint_motions(model, prm, q)
    X = jnp.concatenate([qJ, RJ.reshape(B, 9), tJ], -1)
    for anc in rounds:  # D_i <- D_anc o D_i, anc jumping 1, 2, 4, ... levels up
        X = jnp.where((anc >= 0)[:, None], _compose(X[np.maximum(anc, 0)], X), X)
    qD, R, tD = X[:, :4], X[:, 4:13].reshape(B, 3, 3), X[:, 13:]
    S, own = _subspaces(model, prm, R, tD, qb, x)
    quat = normalize(quat_mul(qD, prm["ref_quat"]))
    rot = mm(R, prm["ref_rot"])
    pos = mv(R, prm["ref_pos"]) + tD
    vb = jnp.concatenate([v, jnp.zeros(1, q.dtype)])[vidx]  # (B, K)
    Sv_par = jnp.sum(S * jnp.where(own, 0.0, vb)[:, None, :], -1)
    # a free joint's rotation columns turn with the body itself (traced only where one exists)
    Sv_own = jnp.sum(S * jnp.where(own, vb, 0.0)[:, None, :], -1) if own.any() else None
    vel = static_mm(A, Sv_par if Sv_own is None else Sv_par + Sv_own)
    c = _cross_motion(jnp.concatenate([vel, jnp.zeros((1, 6), vel.dtype)])[par], Sv_par)
    if Sv_own is not None:
        c = c + _cross_motion(vel, Sv_own)
    acc0 = static_mm(A, c)
    S_dof = S[dof_body, :, dof_col]  # (nv, 6)
    jac = A[:, None, dof_body] * S_dof.T[None]  # (B, 6, nv)
    com = pos + mv(rot, prm["com"])
    I_world = mm(mm(rot, prm["inertia"]), jnp.swapaxes(rot, -1, -2))
    inertia6 = spatial_inertia(prm["mass"], I_world, com)
    ang = vel[:, :3]
    vcom = vel[:, 3:] + jnp.cross(ang, com)
    S_list = tuple(S[i, :, :model.joints[i].nv] for i in range(B))
    return Kin(pos, quat, rot, com, ang, vcom, q, v, vel, jac, c, inertia6, S_list, acc0)


def static_mm(A, X):
    """A @ X for a static 0/1 matrix A: small products as a broadcast product and a sum (one
    fused kernel, where a dot of these sizes is a library call of its own), larger ones as a
    dot (XLA CPU runs the broadcast sum of a 20-link chain's composite inertias, 20 x 20 x 36,
    through XNNPACK at 4x the time of the dot)."""
    if A.shape[0] * A.shape[1] * X.shape[-1] > FUSED_MM_MAX:
        return jnp.dot(jnp.asarray(A, X.dtype), X)
    return jnp.sum(jnp.asarray(A, X.dtype)[:, :, None] * X[None], 1)


def _cross_motion(v, m):
    """Spatial cross product v x m of motion vectors, batched (..., 6)."""
    w, vo = v[..., :3], v[..., 3:]
    return jnp.concatenate([jnp.cross(w, m[..., :3]),
                            jnp.cross(w, m[..., 3:]) + jnp.cross(vo, m[..., :3])], -1)


def dof_forces(model: PhysicsModel, kin: Kin, f):
    """Generalized forces of spatial forces f (B, 6) at the origin on each body: S_j . (A^T f)."""
    _, A, dof_body, _, _, _ = _tables(model)
    # (B, 6) each body's subtree total, as a dot: a fused sum would be inlined into the gather
    # and sum below and recomputed per dof (measured: chain10's step 16.6 -> 14.1 us)
    sub = jnp.dot(jnp.asarray(A.T, f.dtype), f)
    S = _dof_columns(model, kin)
    return jnp.sum(S * sub[dof_body], -1)


def tree_mass_matrix(model: PhysicsModel, kin: Kin):
    """M (nv, nv) by composite inertias: M[j, k] = S_j . (Ic_k S_k) where j's body is k's or an
    ancestor of it, and its transpose."""
    _, A, dof_body, _, _, _ = _tables(model)
    Ic = static_mm(A.T, kin.inertia.reshape(-1, 36)).reshape(-1, 6, 6)
    S = _dof_columns(model, kin)
    F = mv(Ic[dof_body], S)  # (nv, 6)
    M1 = jnp.sum(S[:, None, :] * F[None], -1)  # M1[j, k] = S_j . F_k
    up = A[dof_body][:, dof_body].T > 0  # up[j, k]: j's body is k's or an ancestor of k's
    return jnp.where(up, M1, jnp.where(up.T, M1.T, 0.0))


def tree_bias(model: PhysicsModel, kin: Kin):
    """C(q, v) v: the dof forces of each body's inertial force at zero joint acceleration."""
    return dof_forces(model, kin, _inertial(kin))


def _inertial(kin: Kin):
    """(B, 6) each body's inertial force at zero joint acceleration: I a0 + v x* I v."""
    I, vel = kin.inertia, kin.vel
    return mv(I, kin.acc0) + cross_force(vel, mv(I, vel))


def tree_accel(model: PhysicsModel, kin: Kin, load, tau=None):
    """qdd = M^-1 (tau + J^T f - bias) by one Cholesky solve (the applied and inertial forces
    summed over subtrees in one product); written out (``dense``) where loops are one kernel."""
    f = jnp.concatenate([load.torque + jnp.cross(kin.com, load.force), load.force], -1)
    gen = load.joint + dof_forces(model, kin, f - _inertial(kin))
    if tau is not None:
        gen = gen + tau
    M = tree_mass_matrix(model, kin)
    if model.nv == 1:
        return gen / M[0]
    if xla_flags.in_effect():  # no LAPACK call: the loop can be one kernel
        return spd_solve(M, gen)
    return cho_solve(cho_factor(M), gen)  # fewer operations, where each is a call


def _dof_columns(model: PhysicsModel, kin: Kin):
    """(nv, 6) each dof's own motion column (read off the Jacobian's diagonal blocks)."""
    _, _, dof_body, _, _, _ = _tables(model)
    return kin.jac[dof_body, :, np.arange(model.nv)]

