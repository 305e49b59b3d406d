"""Numeric parameters of a PhysicsModel, evaluated from the unknowns' values inside the traced function.

Every number a prior can sit on flows through here: masses, sizes, inertia, reference poses,
joint anchors/axes and DH parameters, initial state, effect parameters. Pure in ``values``.
"""
from __future__ import annotations

import jax.numpy as jnp

from ..expr import Const, evaluate
from ..scene import Scene
from . import inertia as inr
from . import welds
from .free import free_inverse_inertia
from .spatial import normalize, quat_axis_angle, quat_conj, quat_mul, quat_to_mat, rotate
from .structure import PhysicsModel

_ID_QUAT = Const((1.0, 0.0, 0.0, 0.0))
_ZERO3 = Const((0.0, 0.0, 0.0))


def _ev(expr, values, default=None):
    if expr is None:
        expr = default
    return evaluate(expr, values) if expr is not None else None


def shape_size(shape, values) -> dict:
    return {k: evaluate(e, values) for k, e in shape.size.items()}


def _body_mass_props(scene: Scene, i: int, fixed: bool, values):
    """mass, inertia (3,3) about COM in body axes, COM in body frame, volume, contact size."""
    b = scene.bodies[i]
    kind = b.shape.kind if b.shape is not None else None
    size = shape_size(b.shape, values) if b.shape is not None else {}
    com = jnp.zeros(3)
    unit_i = None
    if kind == "mesh":
        vol, c, ui = inr.mesh_properties(str(b.shape.mesh_path))
        vol, com, unit_i = jnp.asarray(vol), jnp.asarray(c), jnp.asarray(ui)
    elif kind is not None:
        vol = inr.volume(kind, size)
        unit_i = jnp.diag(inr.unit_inertia(kind, size))
    else:
        vol = jnp.asarray(0.0)
    if b.mass is not None:
        mass = evaluate(b.mass, values)
    elif b.density is not None:
        mass = evaluate(b.density, values) * vol
    else:
        mass = jnp.asarray(0.0)
    if b.inertia is not None:
        inertia = jnp.diag(evaluate(b.inertia, values))
    elif unit_i is not None:
        inertia = mass * unit_i
    else:
        inertia = jnp.zeros((3, 3))
    csize = inr.contact_size(kind, size) if kind in inr.SHAPE_KINDS else jnp.zeros(3)
    return mass, inertia, com, vol, csize


def _dh_transform(dh, values, q_offset_theta=0.0, q_offset_d=0.0):
    """Classic DH: Rz(theta) Tz(d) Tx(a) Rx(alpha) as (quat, translation)."""
    a, alpha = evaluate(dh.a, values), evaluate(dh.alpha, values)
    d, theta = evaluate(dh.d, values) + q_offset_d, evaluate(dh.theta, values) + q_offset_theta
    ez, ex = jnp.array([0.0, 0.0, 1.0]), jnp.array([1.0, 0.0, 0.0])
    qz = quat_axis_angle(ez, theta)
    quat = quat_mul(qz, quat_axis_angle(ex, alpha))
    trans = jnp.array([0.0, 0.0, 1.0]) * d + rotate(qz, ex * a)
    return quat, trans


def reference_poses(scene: Scene, model: PhysicsModel, values):
    """Per body, at the reference configuration: position, orientation (body -> world), and its
    joint's world anchor and axis (the kinematics' geometry; DH frames composed down the
    chain). Lists of B arrays."""
    B = model.nbody
    ref_pos: list = [None] * B
    ref_quat: list = [None] * B
    frame: list = [None] * B  # DH frame (quat, pos) of each body at the reference configuration
    anchor: list = [jnp.zeros(3)] * B
    axis: list = [jnp.array([0.0, 0.0, 1.0])] * B
    for i in model.order:
        b, tj = scene.bodies[i], model.joints[i]
        pos = _ev(b.position, values, _ZERO3)
        quat = normalize(_ev(b.orientation, values, _ID_QUAT))
        joint = scene.joints[tj.scene_joint] if tj.scene_joint is not None else None
        if tj.dh:
            fq, fp = (frame[tj.parent] if tj.parent >= 0
                      else (jnp.array([1.0, 0.0, 0.0, 0.0]), jnp.zeros(3)))
            dq, dp = _dh_transform(joint.dh, values)
            cq, cp = quat_mul(fq, dq), fp + rotate(fq, dp)
            frame[i] = (cq, cp)
            anchor[i] = fp
            axis[i] = rotate(fq, jnp.array([0.0, 0.0, 1.0]))
            # body position/orientation are offsets within its DH frame
            ref_pos[i] = cp + rotate(cq, pos) if b.position is not None else cp
            ref_quat[i] = quat_mul(cq, quat)
        else:
            ref_pos[i], ref_quat[i] = pos, quat
            frame[i] = (quat, pos)
            if joint is not None:
                anchor[i] = _ev(joint.anchor, values) if joint.anchor is not None else pos
                if joint.axis is not None:
                    axis[i] = normalize(evaluate(joint.axis, values))

    return ref_pos, ref_quat, anchor, axis


def evaluate_params(scene: Scene, model: PhysicsModel, values) -> dict:
    """The params pytree: per-body arrays (B, ...), joint anchors/axes, q0/v0, effect params."""
    B = model.nbody
    masses, inertias, coms, vols, csizes = [], [], [], [], []
    for i in range(B):
        m, I, c, v, s = _body_mass_props(scene, i, model.joints[i].kind == "fixed", values)
        masses.append(m), inertias.append(I), coms.append(c), vols.append(v), csizes.append(s)
    ref_pos, ref_quat, anchor, axis = reference_poses(scene, model, values)
    ref_rot = quat_to_mat(jnp.stack(ref_quat))

    q0, v0 = [], []
    for i in model.order:
        b, tj = scene.bodies[i], model.joints[i]
        joint = scene.joints[tj.scene_joint] if tj.scene_joint is not None else None
        if tj.kind == "free":
            vel = _ev(b.velocity, values, _ZERO3)
            w = _ev(b.angular_velocity, values, _ZERO3)
            q0 += [ref_pos[i], ref_quat[i]]
            v0 += [vel, ref_rot[i].T @ w]  # angular velocity stored in the body frame
        elif tj.kind == "ball":
            qb = normalize(_ev(joint.initial, values, _ID_QUAT))
            w = _ev(joint.initial_velocity, values, _ZERO3)
            q0.append(qb)
            v0.append(quat_to_mat(qb).T @ w)
        elif tj.kind in ("hinge", "slider"):
            q0.append(jnp.reshape(_ev(joint.initial, values, Const(0.0)), (1,)))
            v0.append(jnp.reshape(_ev(joint.initial_velocity, values, Const(0.0)), (1,)))
    cat = lambda xs: jnp.concatenate([jnp.ravel(x) for x in xs]) if xs else jnp.zeros(0)  # noqa: E731

    effects = []
    for use in scene.effects:
        effects.append({k: evaluate(e, values) for k, e in use.params.items()})
    inertia = jnp.stack(inertias)
    out = {
        "mass": jnp.stack(masses), "inertia": inertia, "com": jnp.stack(coms),
        "volume": jnp.stack([jnp.asarray(v, dtype=float) for v in vols]),
        "size": jnp.stack(csizes),
        "ref_pos": jnp.stack(ref_pos), "ref_quat": jnp.stack(ref_quat),
        "ref_rot": ref_rot,
        "anchor": jnp.stack(anchor), "axis": jnp.stack(axis),
        "q0": cat(q0), "v0": cat(v0), "effects": effects,
    }
    if model.free_bodies is not None:
        out["free_inv_inertia"] = free_inverse_inertia(model, inertia)
    fused = welds.fuse(model)
    if fused is not None:  # once per rollout, not per step
        out["core"] = welds.core_params(fused, out)
    return out


def relative_quat(a, b):
    """Quaternion r with b = r * a."""
    return quat_mul(b, quat_conj(a))
