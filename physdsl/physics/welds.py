"""Welded bodies merged into the body they are welded to, for the dynamics (MuJoCo's fusestatic).

A body on a ``fixed`` joint under another body moves rigidly with it, so the tree's kinematics
and dynamics run over the *core* bodies alone (each with the composite mass, centre of mass
and inertia of itself and the bodies welded below it), and the welded bodies' poses and
velocities are read off their core body's afterwards (``expand``). Effects, contacts and
observations still see every body; their loads are summed onto the core bodies
(``core_load``). A pendulum's rod and bob on one hinge then step as one body. Only where it
pays (``pays``; measured: ``benchmarks/physics.py --welded``).
"""
from __future__ import annotations

import weakref
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import xla_flags
from . import tree
from .effects.base import Load
from .spatial import mm, mv, quat_conj, quat_mul, spatial_inertia
from .structure import PhysicsModel, TreeJoint

_CACHE: "weakref.WeakKeyDictionary[PhysicsModel, Fused | None]" = weakref.WeakKeyDictionary()
# per-body params the core bodies take from their own row (mass, com, inertia: composites)
_BODY_ROWS = ("ref_pos", "ref_quat", "ref_rot", "anchor", "axis", "volume", "size")


class Fused(NamedTuple):
    """A model's core (welds merged) and, per body, its core body's row (``root``) and which
    bodies are core (``core_bodies``: their rows in the full model, in core order)."""

    core: PhysicsModel
    root: np.ndarray  # (B,) row in ``core`` of each body's core body
    core_bodies: np.ndarray  # (Bc,) row in the full model of each core body
    members: np.ndarray  # (Bc, B) 1 where the body belongs to the core body


def fuse(model: PhysicsModel) -> Fused | None:
    """``model``'s core with its welds merged, or None where no body is welded to a moving one
    (a body welded to the world stays a body of its own: it never moves) or merging does not
    pay (``pays``)."""
    if model not in _CACHE:
        fused = _fuse(model)
        _CACHE[model] = fused if fused is not None and pays(fused.core) else None
    return _CACHE[model]


def pays(core: PhysicsModel) -> bool:
    """Whether stepping ``core`` beats stepping every body (``benchmarks/physics.py --welded``,
    side by side; docs/physics.md): a core of one moving body, whose tree operations collapse
    (1.00-1.46x; with one-kernel loops 1.16-1.26x), or the tree path where loops are one kernel
    and flops count (10 links 1.44-1.57x). Elsewhere a step costs its count of operations,
    which merging does not lower, while reading the welded bodies off the core adds some (5
    links 0.79-1.05x, 10 links 0.90-1.13x; one-kernel loops on the recursive path, 5 links,
    0.86-1.08x)."""
    if sum(j.nv > 0 for j in core.joints) == 1:
        return True
    return xla_flags.in_effect() and tree.applies(core)


def _welded(j: TreeJoint) -> bool:
    return j.kind == "fixed" and j.parent >= 0


def _fuse(model: PhysicsModel) -> Fused | None:
    if not any(_welded(j) for j in model.joints):
        return None
    root_full = np.arange(model.nbody)
    for i in model.order:  # parents first: a welded body's parent already points at its root
        j = model.joints[i]
        if _welded(j):
            root_full[i] = root_full[j.parent]
    core_bodies = np.array([i for i in range(model.nbody) if not _welded(model.joints[i])])
    row = {int(b): k for k, b in enumerate(core_bodies)}
    # a joint under a welded body hangs from that body's core body (the weld holds their
    # reference poses, in which joint axes and anchors are given)
    joints = tuple(
        TreeJoint(j.kind, row[b], row[int(root_full[j.parent])] if j.parent >= 0 else -1,
                  j.qadr, j.nq, j.vadr, j.nv, j.scene_joint, j.dh)
        for b, j in ((int(b), model.joints[int(b)]) for b in core_bodies))
    order = tuple(row[i] for i in model.order if i in row)
    children = tuple(tuple(c.body for c in joints if c.parent == k) for k in range(len(joints)))
    core = PhysicsModel(
        body_names=tuple(model.body_names[b] for b in core_bodies),
        joint_names=model.joint_names, shape_kinds=tuple(model.shape_kinds[b] for b in core_bodies),
        joints=joints, order=order, children=children, nq=model.nq, nv=model.nv, sites=(),
        pairs=(), ncon=model.ncon, integrator=model.integrator,
        contact_model=model.contact_model, dt=model.dt, substeps=model.substeps,
        nsteps=model.nsteps, free_bodies=None)
    root = np.array([row[int(r)] for r in root_full])
    members = (root[None, :] == np.arange(len(core_bodies))[:, None]).astype(float)
    return Fused(core, root, core_bodies, members)


def _sum_members(fused: Fused, x):
    """(Bc, ...) each core body's sum of ``x`` (B, ...) over its members (``tree.static_mm``)."""
    flat = x.reshape(x.shape[0], -1)
    return tree.static_mm(fused.members, flat).reshape((fused.members.shape[0],) + x.shape[1:])


def core_params(fused: Fused, prm: dict) -> dict:
    """The core model's per-body params (``params.evaluate_params`` keeps them as
    ``prm["core"]``): each core body's own rows, with the mass, centre of mass (in its body
    frame) and inertia (about that centre, body axes) of it and its welded bodies, from their
    reference poses (at which the weld holds them)."""
    R = prm["ref_rot"]  # (B, 3, 3)
    m = prm["mass"]
    com_w = prm["ref_pos"] + mv(R, prm["com"])  # (B, 3) world centres at the reference pose
    mc = _sum_members(fused, m)
    mc_safe = jnp.where(mc > 0, mc, 1.0)
    cc_w = _sum_members(fused, m[:, None] * com_w) / mc_safe[:, None]  # (Bc, 3)
    d = com_w - cc_w[fused.root]
    eye = jnp.eye(3, dtype=d.dtype)
    I_w = (mm(mm(R, prm["inertia"]), jnp.swapaxes(R, -1, -2))
           + m[:, None, None] * (jnp.sum(d * d, -1)[:, None, None] * eye
                                 - d[:, :, None] * d[:, None, :]))
    Ic_w = _sum_members(fused, I_w)
    rows = fused.core_bodies
    Rc = R[rows]
    out = {k: prm[k][rows] for k in _BODY_ROWS}
    out["mass"] = mc
    out["com"] = mv(jnp.swapaxes(Rc, -1, -2), cc_w - prm["ref_pos"][rows])
    out["inertia"] = mm(mm(jnp.swapaxes(Rc, -1, -2), Ic_w), Rc)
    return out


def expand(fused: Fused, prm: dict, core):
    """The full model's Kin from the core's (``core``): each welded body moves as its core body
    (the same rigid motion D, spatial velocity, Jacobian and bias acceleration), placed at its
    own reference pose; ``core`` rides along for the dynamics (``Kin.core``)."""
    r, rows = fused.root, fused.core_bodies
    core = jax.lax.optimization_barrier(core)
    Rref_c = prm["ref_rot"][rows]
    RD = mm(core.rot, jnp.swapaxes(Rref_c, -1, -2))[r]  # (B, 3, 3) each body's rigid motion
    tD = (core.pos - mv(RD[rows], prm["ref_pos"][rows]))[r]
    qD = quat_mul(core.quat, quat_conj(prm["ref_quat"][rows]))[r]
    pos = mv(RD, prm["ref_pos"]) + tD
    quat = quat_mul(qD, prm["ref_quat"])
    rot = mm(RD, prm["ref_rot"])
    com = pos + mv(rot, prm["com"])
    ang = core.ang[r]
    vcom = core.vcom[r] + jnp.cross(ang, com - core.com[r])
    I_world = mm(mm(rot, prm["inertia"]), jnp.swapaxes(rot, -1, -2))
    is_core = np.isin(np.arange(len(r)), rows)
    no_dofs = jnp.zeros((6, 0), pos.dtype)
    S = tuple(core.S[int(r[i])] if is_core[i] else no_dofs
              for i in range(len(r))) if core.S is not None else None
    # a weld's own joint adds no bias acceleration (c_i is the joint's term, not its sum)
    bias_acc = jnp.where(is_core[:, None], core.bias_acc[r], 0.0)
    return core._replace(
        pos=pos, quat=quat, rot=rot, com=com, ang=ang, vcom=vcom, vel=core.vel[r],
        jac=core.jac[r], bias_acc=bias_acc, acc0=core.acc0[r],
        inertia=spatial_inertia(prm["mass"], I_world, com), S=S, core=core)


def core_load(fused: Fused, kin, load: Load) -> Load:
    """``load`` (at every body's centre of mass) as the same wrench on each core body (at the
    core body's composite centre of mass)."""
    arm = kin.com - kin.core.com[fused.root]
    torque = load.torque + jnp.cross(arm, load.force)
    return Load(_sum_members(fused, load.force), _sum_members(fused, torque), load.joint)
