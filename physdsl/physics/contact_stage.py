"""Contact integration: detection per candidate pair, contact Jacobians, then either the LCP
velocity step or compliant (penalty) forces, by ``scene.world.contact_model``.

Rows of the contact arrays are the candidates of every pair in ``model.pairs`` order (static
count K per pair). Friction uses a 4-edge polyhedral cone (+-t1, +-t2) in the LCP model; a
scene without any friction effect has no friction directions at all (F = 0).
Normals point from body b towards body a, so a positive normal impulse
pushes a away from b.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import contact as cm
from . import dense
from .effects.base import Load
from .kinematics import Kin
from .rows import place, take
from .spatial import mtv, mv, normalize, skew
from .structure import PhysicsModel


class Contacts(NamedTuple):
    dist: jnp.ndarray  # (C,)
    normal: jnp.ndarray  # (C, 3)
    active: jnp.ndarray  # (C,) bool
    J: jnp.ndarray  # (C, 3, nv) relative point-velocity Jacobian (a minus b), world axes
    Jn: jnp.ndarray  # (C, nv)
    Jt: jnp.ndarray  # (C, 4, nv) along the friction directions t1, t2, -t1, -t2; (C, 0, nv) without friction
    mu: jnp.ndarray  # (C,)
    e: jnp.ndarray  # (C,)
    # (C,) Jn M^-1 Jn^T in closed form (free bodies, contact models other than the LCP)
    inv_mass: jnp.ndarray | None = None
    valid: jnp.ndarray | None = None  # (C,) bool, candidates that exist whatever their gap
    point_a: jnp.ndarray | None = None  # (C, 3) world contact point on a
    point_b: jnp.ndarray | None = None  # (C, 3) world contact point on b
    # (C,) trace of the tangential block of J M^-1 J^T in closed form (free bodies only): an
    # upper bound of the inverse effective mass friction meets
    inv_mass_t: jnp.ndarray | None = None


SLIP_ALIGN = 1e-3  # m/s: slip speeds well above this turn the friction pyramid onto the slip


def tangents(n, slip=None):
    """Two unit tangents orthogonal to unit normal n (smooth away from the switch plane).

    With ``slip`` (the contact's relative velocity), t1 turns towards its tangential part: the
    4-edge pyramid then has an edge exactly against the sliding direction, so sliding friction
    is mu N opposite the slip in any direction (a fixed pyramid brakes a diagonal slide by up to
    sqrt(2) mu N and bends it towards an edge). The blend with the fixed tangent is continuous
    and leaves stick (slip well below ``SLIP_ALIGN``) on the fixed pyramid.
    """
    a = jnp.where(jnp.abs(n[0]) < 0.9, jnp.array([1.0, 0.0, 0.0]), jnp.array([0.0, 1.0, 0.0]))
    t1 = normalize(jnp.cross(n, a))
    if slip is not None:
        st = slip - jnp.dot(slip, n) * n
        t1 = normalize(st + SLIP_ALIGN * t1)
    return t1, jnp.cross(n, t1)


def _point_jac(kin: Kin, bodies, points):
    """(P, K, 3, nv) Jacobians of body-fixed points ``points`` (P, K, 3) on ``bodies`` (P,)."""
    J = kin.jac[bodies]  # (P, 6, nv)
    return J[:, None, 3:] - jnp.einsum("pkij,pjn->pkin", skew(points), J[:, :3])


def detect_all(model: PhysicsModel, prm: dict, kin: Kin, v=None) -> Contacts:
    """Contact candidates of every pair with their Jacobians and coefficients; with the joint
    velocity ``v``, friction pyramids are aligned with each contact's slip (``tangents``).

    Pairs of the same shape kinds are detected together (vmap), so the traced graph grows with
    the number of kind combinations, not with the number of pairs.
    """
    C, nv = model.ncon, model.nv
    dist = jnp.zeros(C)
    normal = jnp.zeros((C, 3))
    valid = jnp.zeros(C, bool)
    J = jnp.zeros((C, 3, nv))
    mu = jnp.zeros(C)
    e = jnp.ones(C)
    # free bodies' effective masses in closed form: the LCP never reads them (a third of the
    # billiards Gauss-Newton program's StableHLO, 23 078 -> 14 896 lines)
    free = model.free_bodies is not None and model.contact_model != "lcp"
    inv_m = jnp.zeros(C) if free else None
    inv_t = jnp.zeros(C) if free else None
    pt_a, pt_b = jnp.zeros((C, 3)), jnp.zeros((C, 3))
    groups: dict = {}
    for pair in model.pairs:
        groups.setdefault((pair.kind_a, pair.kind_b), []).append(pair)
    for (ka, kb), pairs in groups.items():
        ia = jnp.asarray([p.a for p in pairs])
        ib = jnp.asarray([p.b for p in pairs])
        rows = jnp.asarray([p.rows for p in pairs])  # (P, K)
        cp = jax.vmap(lambda pa, qa, sa, pb, qb, sb: cm.detect(ka, kb, pa, qa, sa, pb, qb, sb,
                                                               margin=jnp.inf))(
            kin.pos[ia], kin.quat[ia], prm["size"][ia], kin.pos[ib], kin.quat[ib], prm["size"][ib])
        Jrel = _point_jac(kin, ia, cp.point_a) - _point_jac(kin, ib, cp.point_b)
        dist = dist.at[rows].set(cp.dist)
        normal = normal.at[rows].set(cp.normal)
        pt_a, pt_b = pt_a.at[rows].set(cp.point_a), pt_b.at[rows].set(cp.point_b)
        valid = valid.at[rows].set(cp.active)  # no margin given: active means valid here
        J = J.at[rows].set(Jrel)
        if free:
            ka_ = np.asarray([p.a for p in pairs])
            kb_ = np.asarray([p.b for p in pairs])
            inv_m = inv_m.at[rows].set(_inv_mass(model, prm, kin, ka_, cp.point_a, cp.normal)
                                       + _inv_mass(model, prm, kin, kb_, cp.point_b, cp.normal))
            inv_t = inv_t.at[rows].set(sum(
                _inv_mass(model, prm, kin, ka_, cp.point_a, t) + _inv_mass(model, prm, kin, kb_, cp.point_b, t)
                for t in jax.vmap(jax.vmap(tangents))(cp.normal)))
        fr = jnp.stack([jnp.asarray(prm["effects"][p.friction]["coefficient"], dtype=float)
                        if p.friction is not None else jnp.asarray(0.0) for p in pairs])
        re = jnp.stack([jnp.asarray(prm["effects"][p.restitution]["coefficient"], dtype=float)
                        if p.restitution is not None else jnp.asarray(1.0) for p in pairs])
        mu = mu.at[rows].set(jnp.broadcast_to(fr[:, None], rows.shape))
        e = e.at[rows].set(jnp.broadcast_to(re[:, None], rows.shape))
    Jn = jnp.einsum("ck,ckn->cn", normal, J)
    if any(p.friction is not None for p in model.pairs):
        if v is None:
            t1, t2 = jax.vmap(tangents)(normal)
        else:
            t1, t2 = jax.vmap(tangents)(normal, jnp.einsum("ckn,n->ck", J, v))
        T = jnp.stack([t1, t2, -t1, -t2], 1)  # (C, 4, 3): polyhedral cone with 4 edges
    else:  # no friction anywhere: the LCP keeps its normal rows only
        T = jnp.zeros((C, 0, 3), normal.dtype)
    Jt = jnp.einsum("cfk,ckn->cfn", T, J)
    return Contacts(dist, normal, valid & (dist < cm.contact_margin), J, Jn, Jt, mu, e, inv_m,
                    valid, pt_a, pt_b, inv_t)


def closing_within(con: Contacts, v_free, h) -> Contacts:
    """``con`` with every candidate whose gap the free motion closes within this step active too:
    a body faster than margin / h could otherwise start a step farther than the margin and end
    it inside the other (its impact found a step late, a jump in the trajectory)."""
    closing = con.valid & (con.dist + h * (con.Jn @ v_free) < 0)
    return con._replace(active=con.active | closing)


def _inv_mass(model: PhysicsModel, prm: dict, kin: Kin, bodies, points, normal):
    """(P, K) contribution 1/m + (r x n).I^-1 (r x n) of free ``bodies`` (P,) to the inverse
    effective mass of contacts at ``points`` (P, K, 3) along ``normal``; 0 for static bodies."""
    fb = model.free_bodies
    B = model.nbody
    inv_i = place(jnp.zeros((B, 3, 3)), fb, prm["free_inv_inertia"])[bodies]
    inv_m = place(jnp.zeros(B), fb, 1.0 / take(prm["mass"], fb))[bodies]
    rxn = jnp.cross(points - kin.com[bodies][:, None], normal)
    u = mtv(kin.rot[bodies][:, None], rxn)  # body axes
    return inv_m[:, None] + jnp.sum(u * mv(inv_i[:, None], u), -1)


def compliant_tau(model: PhysicsModel, con: Contacts, M, v, h=None):
    """Generalized contact forces of the compliant model and the normal force per row.

    The effective masses per row come from ``con.inv_mass``/``inv_mass_t`` when set (free
    bodies: M is not needed, pass None), else from one solve with M. ``h``: the explicit step
    the forces serve, which widens the friction's smoothing (``friction_step``)."""
    vrel = jnp.einsum("ckn,n->ck", con.J, v)
    vn = jnp.sum(vrel * con.normal, -1)
    vt = vrel - vn[:, None] * con.normal
    if con.inv_mass is not None:
        inv_meff, inv_t = con.inv_mass, con.inv_mass_t
    elif all(p.friction is None for p in model.pairs):
        inv_meff, inv_t = jnp.sum(con.Jn * dense.solve(M, con.Jn.T).T, -1), None
    else:
        C, _, nv = con.J.shape
        W = jnp.einsum("ckn,cln->ckl", con.J,
                       dense.solve(M, con.J.reshape(3 * C, nv).T).T.reshape(C, 3, nv))
        inv_meff = jnp.einsum("ck,ckl,cl->c", con.normal, W, con.normal)  # n J M^-1 J^T n
        inv_t = jnp.trace(W, axis1=1, axis2=2) - inv_meff
    meff = 1.0 / jnp.where(inv_meff > 0, inv_meff, 1.0)
    fn, ft = cm.compliant_forces(con.dist, vn, vt, con.mu, con.e, meff,
                                 step=friction_step(model, con, h, inv_t))
    fn = jnp.where(con.active, fn, 0.0)
    ft = jnp.where(con.active[:, None], ft, 0.0)
    F = fn[:, None] * con.normal + ft  # world force on a (and -F on b) at the contact
    tau = jnp.einsum("ckn,ck->n", con.J, F)
    return tau, fn


def friction_step(model: PhysicsModel, con: Contacts, h, inv_mass_t):
    """What widens compliant friction's smoothing for an explicit step of length ``h`` (None:
    nothing; nor without friction anywhere)."""
    if h is None or inv_mass_t is None or all(p.friction is None for p in model.pairs):
        return None
    pair = np.zeros(model.ncon, int)
    for k, p in enumerate(model.pairs):
        pair[list(p.rows)] = k
    return cm.FrictionStep(h, inv_mass_t, con.active, pair)


def compliant_load(model: PhysicsModel, kin: Kin, con: Contacts, h=None):
    """Free-body scenes: the compliant contact forces as a Load (each contact's force and its
    moment about the centre of mass, on a, and their opposite on b) and the normal force per
    row, from the bodies' own velocities: no (C, 3, nv) contact Jacobian, whose size grows as
    pairs x dofs (the same forces as ``compliant_tau``, to rounding). ``h``: as there."""
    ra, rb = _row_bodies(model)
    ca, cb = kin.com[ra], kin.com[rb]
    vel = lambda r, p, c: kin.vcom[r] + jnp.cross(kin.ang[r], p - c)  # noqa: E731
    vrel = vel(ra, con.point_a, ca) - vel(rb, con.point_b, cb)
    vn = jnp.sum(vrel * con.normal, -1)
    vt = vrel - vn[:, None] * con.normal
    meff = 1.0 / jnp.where(con.inv_mass > 0, con.inv_mass, 1.0)
    fn, ft = cm.compliant_forces(con.dist, vn, vt, con.mu, con.e, meff,
                                 step=friction_step(model, con, h, con.inv_mass_t))
    fn = jnp.where(con.active, fn, 0.0)
    F = fn[:, None] * con.normal + jnp.where(con.active[:, None], ft, 0.0)
    B = model.nbody
    force = jnp.zeros((B, 3), F.dtype).at[ra].add(F).at[rb].add(-F)
    torque = (jnp.zeros((B, 3), F.dtype).at[ra].add(jnp.cross(con.point_a - ca, F))
              .at[rb].add(-jnp.cross(con.point_b - cb, F)))
    return Load(force, torque, jnp.zeros(model.nv, F.dtype)), fn


def _row_bodies(model: PhysicsModel):
    """(C,) static body a and body b of each contact row."""
    ra, rb = np.zeros(model.ncon, int), np.zeros(model.ncon, int)
    for p in model.pairs:
        ra[list(p.rows)], rb[list(p.rows)] = p.a, p.b
    return ra, rb


def lcp_velocity(model: PhysicsModel, con: Contacts, M, v, v_free, h, warm=None):
    """Next velocity from the LCP step, the velocity that advances positions (with the
    time-of-impact correction, see ``contact.step``), the normal force (impulse / h) per row
    and the LCP's solution (the next step's ``warm`` start)."""
    out = cm.solve_lcp_step(M, v_free, con.Jn, con.Jt, con.mu, con.e, con.Jn @ v, con.dist,
                            con.active, h, warm=warm)
    return out.v, out.v_position, out.lam_n / h, out.solution


def lcp_rows(model: PhysicsModel) -> int:
    """Rows of the model's contact LCP (``contact.lcp_size``): 4 friction directions per
    contact where any pair has friction (``detect_all``)."""
    friction = any(p.friction is not None for p in model.pairs)
    return cm.lcp_size(model.ncon, 4 if friction else 0)
