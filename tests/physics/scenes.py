"""Small Scene builders for physics tests (no parser needed)."""
from __future__ import annotations

import numpy as np

from physdsl.expr import Const, Expr, Ref, Vec
from physdsl.scene import Body, EffectUse, Joint, Scene, Shape, World

G = (0.0, 0.0, -9.81)


def c(x) -> Expr:
    """A constant Expr from a number or a sequence."""
    if isinstance(x, (int, float)):
        return Const(float(x))
    return Const(tuple(float(v) for v in x))


def e(x) -> Expr:
    """Expr from a number, a sequence (items may be Exprs or names) or a name (an unknown)."""
    if isinstance(x, str):
        return Ref(x)
    if isinstance(x, (int, float)):
        return Const(float(x))
    if isinstance(x, (Const, Ref, Vec)) or not hasattr(x, "__len__"):
        return x
    if all(isinstance(v, (int, float)) for v in x):
        return c(x)
    return Vec(tuple(e(v) for v in x))


def sphere(name, r=0.1, mass=1.0, pos=(0, 0, 0), vel=None, angvel=None, **kw) -> Body:
    return Body(name, Shape("sphere", {"radius": e(r)}), mass=e(mass), position=e(pos),
                velocity=e(vel) if vel is not None else None,
                angular_velocity=e(angvel) if angvel is not None else None, **kw)


def box(name, size=(0.1, 0.1, 0.1), mass=1.0, pos=(0, 0, 0), **kw) -> Body:
    return Body(name, Shape("box", {"size": e(size)}), mass=e(mass), position=e(pos), **kw)


def capsule(name, r, length, mass, pos, **kw) -> Body:
    return Body(name, Shape("capsule", {"radius": e(r), "length": e(length)}), mass=e(mass),
                position=e(pos), **kw)


def effect(name, target, **params) -> EffectUse:
    tables = params.pop("tables", {})
    tgt = target if isinstance(target, tuple) else (target,)
    return EffectUse(name, tgt, {k: e(v) for k, v in params.items()}, tables=tables)


def gravity(g=G) -> EffectUse:
    return effect("gravity", "world", acceleration=g)


def scene(bodies, joints=(), effects=(), dt=1e-3, duration=1.0, integrator="semi_implicit_euler",
          substeps=1, contact_pairs=(), contact_model="lcp", name="test") -> Scene:
    return Scene(name=name, world=World(timestep=dt, duration=duration, substeps=substeps,
                                        integrator=integrator, contact_model=contact_model),
                 bodies=tuple(bodies), joints=tuple(joints), effects=tuple(effects),
                 observations=(), cameras=(), unknowns=(), contact_pairs=tuple(contact_pairs))


def pendulum(length=1.0, mass=1.0, r=0.02, angle=0.1, damping=None, dt=1e-3, duration=1.0,
             integrator="rk4", pivot=(0, 0, 1.0)) -> Scene:
    """A point-like bob on a massless rod: hinge about -y at ``pivot``."""
    px, py, pz = pivot
    bob = sphere("bob", r=r, mass=mass, pos=(px, py, pz - length) if not isinstance(length, str)
                 else (px, py, Vec((Const(pz),)).items[0]))
    if isinstance(length, str):
        from physdsl.expr import Binary
        bob = sphere("bob", r=r, mass=mass, pos=e((px, py, Binary("-", Const(pz), Ref(length)))))
    effects = [gravity()]
    if damping is not None:
        effects.append(effect("joint_damping", "hinge", coefficient=damping))
    j = Joint("hinge", "hinge", "world", "bob", axis=c((0, -1, 0)), anchor=c(pivot),
              initial=e(angle), initial_velocity=c(0.0))
    return scene([bob], [j], effects, dt=dt, duration=duration, integrator=integrator)


def chain(n=3, link=0.3, mass=0.5, r=0.02, dt=1e-3, duration=1.0, integrator="rk4",
          angles=None) -> Scene:
    """n capsule links hanging in a chain of hinges about y from (0, 0, 0)."""
    bodies, joints = [], []
    angles = angles if angles is not None else [0.3] + [0.0] * (n - 1)
    for k in range(n):
        bodies.append(capsule(f"link{k}", r, link - 2 * r, mass, (0, 0, -(k + 0.5) * link)))
        joints.append(Joint(f"j{k}", "hinge", "world" if k == 0 else f"link{k - 1}", f"link{k}",
                            axis=c((0, 1, 0)), anchor=c((0, 0, -k * link)),
                            initial=e(angles[k]), initial_velocity=c(0.0)))
    return scene(bodies, joints, [gravity()], dt=dt, duration=duration, integrator=integrator)


def as_np(x):
    return np.asarray(x)
