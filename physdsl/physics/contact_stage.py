"""Contact integration: detection per candidate pair, contact Jacobians, then either the LCP
velocity step or compliant (penalty) forces, by ``scene.world.contact_model``.

Rows of the contact arrays are the candidates of every pair in ``model.pairs`` order (static
count K per pair). Friction uses a 4-edge polyhedral cone (+-t1, +-t2) in the LCP model.
Normals point from body b towards body a, so a positive normal impulse
pushes a away from b.
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from .kinematics import Kin, point_jacobian
from .model import Model
from .spatial import normalize


class Contacts(NamedTuple):
    dist: jnp.ndarray  # (C,)
    normal: jnp.ndarray  # (C, 3)
    active: jnp.ndarray  # (C,) bool
    J: jnp.ndarray  # (C, 3, nv) relative point-velocity Jacobian (a minus b), world axes
    Jn: jnp.ndarray  # (C, nv)
    Jt: jnp.ndarray  # (C, 4, nv) along the friction directions t1, t2, -t1, -t2
    mu: jnp.ndarray  # (C,)
    e: jnp.ndarray  # (C,)


def tangents(n):
    """Two unit tangents orthogonal to unit normal n (smooth away from the switch plane)."""
    a = jnp.where(jnp.abs(n[0]) < 0.9, jnp.array([1.0, 0.0, 0.0]), jnp.array([0.0, 1.0, 0.0]))
    t1 = normalize(jnp.cross(n, a))
    return t1, jnp.cross(n, t1)


def detect_all(model: Model, prm: dict, kin: Kin) -> Contacts:
    """Contact candidates of every pair with their Jacobians and coefficients."""
    from . import contact as cm

    dist, nrm, active, J, mu, e = [], [], [], [], [], []
    for pair in model.pairs:
        a, b = pair.a, pair.b
        cp = cm.detect(pair.kind_a, pair.kind_b, kin.pos[a], kin.quat[a], prm["size"][a],
                       kin.pos[b], kin.quat[b], prm["size"][b])
        K = cp.dist.shape[0]
        for k in range(K):
            J.append(point_jacobian(kin, a, cp.point_a[k]) - point_jacobian(kin, b, cp.point_b[k]))
        dist.append(cp.dist)
        nrm.append(cp.normal)
        active.append(cp.active)
        fr = prm["effects"][pair.friction]["coefficient"] if pair.friction is not None else 0.0
        re = prm["effects"][pair.restitution]["coefficient"] if pair.restitution is not None else 1.0
        mu.append(jnp.broadcast_to(jnp.asarray(fr, dtype=float), (K,)))
        e.append(jnp.broadcast_to(jnp.asarray(re, dtype=float), (K,)))
    normal = jnp.concatenate(nrm)
    J = jnp.stack(J)
    Jn = jnp.einsum("ck,ckn->cn", normal, J)
    t1, t2 = zip(*[tangents(n) for n in normal])
    t1, t2 = jnp.stack(t1), jnp.stack(t2)
    T = jnp.stack([t1, t2, -t1, -t2], 1)  # (C, 4, 3): polyhedral cone with 4 edges
    Jt = jnp.einsum("cfk,ckn->cfn", T, J)
    return Contacts(jnp.concatenate(dist), normal, jnp.concatenate(active), J, Jn, Jt,
                    jnp.concatenate(mu), jnp.concatenate(e))


def compliant_tau(model: Model, con: Contacts, M, v):
    """Generalized contact forces of the compliant model and the normal force per row."""
    from . import contact as cm

    vrel = jnp.einsum("ckn,n->ck", con.J, v)
    vn = jnp.sum(vrel * con.normal, -1)
    vt = vrel - vn[:, None] * con.normal
    Minv_JnT = jnp.linalg.solve(M, con.Jn.T)  # (nv, C)
    inv_meff = jnp.sum(con.Jn * Minv_JnT.T, -1)
    meff = 1.0 / jnp.where(inv_meff > 0, inv_meff, 1.0)
    fn, ft = cm.compliant_forces(con.dist, vn, vt, con.mu, con.e, meff)
    fn = jnp.where(con.active, fn, 0.0)
    ft = jnp.where(con.active[:, None], ft, 0.0)
    F = fn[:, None] * con.normal + ft  # world force on a (and -F on b) at the contact
    tau = jnp.einsum("ckn,ck->n", con.J, F)
    return tau, fn


def lcp_velocity(model: Model, con: Contacts, M, v, v_free, h):
    """Next velocity from the LCP step, and the normal force (impulse / h) per row."""
    from . import contact as cm

    vn_pre = con.Jn @ v
    v_next, lam_n, _ = cm.solve_lcp_step(M, v_free, con.Jn, con.Jt, con.mu, con.e, vn_pre,
                                         con.dist, con.active, h)
    return v_next, lam_n / h
