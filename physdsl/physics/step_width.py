"""The smoothing width a smoothed dry-friction law needs when it is integrated explicitly.

Such a law (joint friction's F tanh(v / eps), rolling resistance's and compliant contact's
F v / sqrt(v^2 + eps^2)) is, near v = 0, a damper of rate F w / eps, w the velocity change a
unit impulse makes (the inverse of the effective mass or inertia the force meets). Integrated
explicitly (the force at the step's or stage's start), a step h with h F w / eps > 2
(semi-implicit Euler; RK4: > 2.79) overshoots: v flips sign each step, grows by
|1 - h F w / eps| per step until |v| ~ eps, and the rollout's derivatives grow without bound.
``step_width`` makes the width never narrower than the velocity change one step of the whole
force makes (h F w / eps <= 1): each step shrinks v without flipping it. Where that change is
well below eps the law is unchanged to a relative (h F w / eps)^2 / 2 of its width, and
motion at |v| >> eps not at all (the law is saturated there).
"""
import jax.numpy as jnp

from .structure import PhysicsModel

ROTATING = ("hinge", "ball", "free")


def step_width(width, h, strength, inverse_inertia):
    """sqrt(width^2 + (h strength inverse_inertia)^2): ``width`` (the law's own eps) widened to
    the velocity change of one step h of the force or torque ``strength`` on a body of inverse
    mass or inertia ``inverse_inertia`` (an upper bound of it: the widening is then enough)."""
    return jnp.sqrt(width ** 2 + (h * strength * inverse_inertia) ** 2)


def least_moment(inertia):
    """A lower bound of the smallest principal moment of the 3x3 ``inertia``, in closed form
    (no eigen-solver in the step): its Gershgorin bound (exact for the primitive shapes'
    diagonal inertia) and 4 det / trace^2 (det over the larger two's mean squared)."""
    off = jnp.sum(jnp.abs(inertia), 1) - jnp.abs(jnp.diagonal(inertia))
    trace = jnp.trace(inertia)
    det = jnp.dot(inertia[0], jnp.cross(inertia[1], inertia[2]))
    return jnp.maximum(jnp.min(jnp.diagonal(inertia) - off),
                       4.0 * det / jnp.where(trace > 0, trace, 1.0) ** 2)


def _inverse(x):
    """1 / x where x > 0, else 0 (no inertia: no bound from this body)."""
    return jnp.where(x > 0, 1.0 / jnp.where(x > 0, x, 1.0), 0.0)


def step_inverse_inertia(model: PhysicsModel, prm, bodies):
    """Sum over ``bodies`` of an upper bound of the inverse principal moments (1/kg m^2), so
    of the angular-velocity change per unit torque impulse on their relative rotation (0 for
    static bodies and for bodies with no rotational inertia)."""
    total = jnp.zeros((), prm["inertia"].dtype)
    for b in bodies:
        if model.ancestors_dofs(b):
            total = total + _inverse(least_moment(prm["inertia"][b]))
    return total


def _welded(model: PhysicsModel, body: int) -> tuple[int, ...]:
    """``body`` and the bodies fixed to it below (through fixed joints only)."""
    out = [body]
    for c in model.children[body]:
        if model.joints[c].kind == "fixed":
            out.extend(_welded(model, c))
    return tuple(out)


def _rotates(model: PhysicsModel, body: int) -> bool:
    """Whether some joint on the path from the world to ``body`` turns it."""
    b = body
    while b >= 0:
        if model.joints[b].nv and model.joints[b].kind in ROTATING:
            return True
        b = model.joints[b].parent
    return False


def _composite(prm, bodies):
    """Mass, world centre of mass and world inertia about it of rigidly joined ``bodies`` at the
    reference configuration."""
    R = [prm["ref_rot"][b] for b in bodies]
    m = [prm["mass"][b] for b in bodies]
    x = [prm["ref_pos"][b] + r @ prm["com"][b] for b, r in zip(bodies, R)]
    mass = sum(m)
    com = sum(mi * xi for mi, xi in zip(m, x)) / jnp.where(mass > 0, mass, 1.0)
    inertia = sum(r @ prm["inertia"][b] @ r.T + _shift(mi, xi - com)
                  for b, r, mi, xi in zip(bodies, R, m, x))
    return mass, com, inertia


def _shift(m, d):
    """Parallel-axis term m (|d|^2 1 - d d^T)."""
    return m * (jnp.dot(d, d) * jnp.eye(3) - jnp.outer(d, d))


def _along(inertia, u):
    """u^T I^-1 u (0 where I is singular: no rotational inertia)."""
    det = jnp.linalg.det(inertia)
    safe = jnp.where(det > 0, inertia, jnp.eye(3))
    return jnp.where(det > 0, jnp.dot(u, jnp.linalg.solve(safe, u)), 0.0)


def joint_inverse_inertia(model: PhysicsModel, prm, site):
    """An upper bound of the rate change per unit generalized impulse of the joint of ``site``
    (1 / the effective inertia or mass it meets), from the parameters alone (configuration
    invariant). Relaxing constraints only lowers the inertia a force meets, so: the child with
    the bodies welded to it (the rest of its subtree dropped); turning about the fixed anchor
    (hinge), translating (slider) or turning about it (ball) where the parent does not move;
    where it moves, child and parent as free bodies, each with the bodies welded to it."""
    child = next(b for b, j in enumerate(model.joints) if j.scene_joint == site.joint)
    kind, parent = model.joints[child].kind, model.joints[child].parent
    mc, xc, Ic = _composite(prm, _welded(model, child))
    a, anchor = prm["axis"][child], prm["anchor"][child]
    moving = parent >= 0 and bool(model.ancestors_dofs(parent))
    if not moving:
        Ia = Ic + _shift(mc, xc - anchor)
        if kind == "hinge":
            return _inverse(jnp.dot(a, Ia @ a))
        if kind == "slider":
            return _inverse(mc)
        return _inverse(least_moment(Ia)) + (_inverse(mc) if kind == "free" else 0.0)
    mp, xp, Ip = _composite(prm, _welded(model, parent))
    turns = _rotates(model, parent)
    if kind == "hinge":
        return _along(Ic, a) + (_along(Ip, a) if turns else 0.0)
    if kind == "slider":  # the force pair's line through either centre of mass
        r = jnp.cross(xc - xp, a)
        through_child = _inverse(mc) + _inverse(mp) + (_along(Ip, r) if turns else 0.0)
        return jnp.minimum(through_child, _inverse(mc) + _inverse(mp) + _along(Ic, r))
    rot = _inverse(least_moment(Ic)) + (_inverse(least_moment(Ip)) if turns else 0.0)
    return rot + (_inverse(mc) + _inverse(mp) if kind == "free" else 0.0)
