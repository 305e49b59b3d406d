"""``build_model(scene)``: the static PhysicsModel of a Scene (``structure.py``), checked:
a tree of joints rooted at world, shapes and masses present, every effect registered
(``effects.EFFECTS``) and acting on a target it may, a registered contact model.
"""
from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..scene import Scene
from . import contact as contact_mod
from .contact_models import CONTACT_MODELS
from .effects import EFFECTS
from .structure import DOFS, SHAPES, ContactPair, PhysicsModel, Site, TreeJoint


def _tree(scene: Scene):
    names = [b.name for b in scene.bodies]
    index = {n: i for i, n in enumerate(names)}
    if len(index) != len(names):
        raise ModelError("two bodies share a name", hint="give every body its own name")
    parent = [-1] * len(names)
    kind: list[str | None] = [None] * len(names)
    sj: list[int | None] = [None] * len(names)
    for ji, j in enumerate(scene.joints):
        if j.child not in index:
            raise ModelError(f"joint '{j.name}' moves unknown body '{j.child}'", span=j.span)
        if j.parent != "world" and j.parent not in index:
            raise ModelError(f"joint '{j.name}' hangs from unknown body '{j.parent}'", span=j.span)
        c = index[j.child]
        if sj[c] is not None:
            raise ModelError(f"body '{j.child}' is the child of two joints", span=j.span,
                             hint="a body has at most one parent joint; use a pair spring for loops")
        if j.kind not in DOFS:
            raise ModelError(f"unknown joint kind '{j.kind}'", span=j.span,
                             hint="use hinge, slider, ball, free or fixed")
        if scene.bodies[c].fixed:
            raise ModelError(f"body '{j.child}' is fixed but moved by joint '{j.name}'", span=j.span,
                             hint="remove `fixed: true` or the joint")
        if j.kind == "free" and j.parent != "world":
            raise ModelError(f"free joint '{j.name}' must hang from world", span=j.span,
                             hint="a body without a joint already moves freely")
        if j.dh is not None and j.kind not in ("hinge", "slider"):
            raise ModelError(f"Denavit-Hartenberg parameters need a hinge or slider, not {j.kind}",
                             span=j.span)
        if j.kind in ("hinge", "slider") and j.axis is None and j.dh is None:
            raise ModelError(f"{j.kind} joint '{j.name}' has no axis", span=j.span,
                             hint="add `axis: (x, y, z)` (world frame at the reference pose)")
        parent[c] = -1 if j.parent == "world" else index[j.parent]
        kind[c] = j.kind
        sj[c] = ji
    for i, b in enumerate(scene.bodies):
        if kind[i] is None:
            is_fixed = b.fixed or (b.shape is not None and b.shape.kind == "plane")
            kind[i] = "fixed" if is_fixed else "free"
        if kind[i] != "fixed" and b.shape is not None and b.shape.kind == "plane":
            raise ModelError(f"plane '{b.name}' cannot move", span=b.span,
                             hint="planes are fixed; use a thin box for a moving slab")
        if b.shape is not None and b.shape.kind not in SHAPES:
            raise ModelError(f"unknown shape '{b.shape.kind}' of body '{b.name}'", span=b.span)
    order: list[int] = []
    state = [0] * len(names)  # 0 new, 1 visiting, 2 done

    def visit(i: int):
        if state[i] == 2:
            return
        if state[i] == 1:
            raise ModelError(f"joints form a loop through body '{names[i]}'",
                             hint="joints must form a tree rooted at world")
        state[i] = 1
        if parent[i] >= 0:
            visit(parent[i])
        state[i] = 2
        order.append(i)

    for i in range(len(names)):
        visit(i)
    return names, index, parent, kind, sj, order


def build_model(scene: Scene) -> PhysicsModel:
    """Static PhysicsModel of ``scene``; raises ModelError for unsupported structure."""
    names, index, parent, kind, sj, order = _tree(scene)
    joints: list[TreeJoint | None] = [None] * len(names)
    qa = va = 0
    for i in order:
        nq, nv = DOFS[kind[i]]
        dh = sj[i] is not None and scene.joints[sj[i]].dh is not None
        joints[i] = TreeJoint(kind[i], i, parent[i], qa, nq, va, nv, sj[i], dh)
        qa += nq
        va += nv
    children = tuple(tuple(c for c in order if parent[c] == i) for i in range(len(names)))
    shape_kinds = tuple(b.shape.kind if b.shape is not None else None for b in scene.bodies)
    for i, b in enumerate(scene.bodies):
        if kind[i] != "fixed" and b.mass is None and b.density is None:
            raise ModelError(f"body '{b.name}' has no mass", span=b.span,
                             hint="give `mass:` or `density:`")
        if kind[i] != "fixed" and b.shape is None and (b.inertia is None or b.mass is None):
            raise ModelError(f"body '{b.name}' has no shape, so it needs mass and inertia", span=b.span)

    pairs, ncon = _contact_pairs(scene, index, shape_kinds)
    sites = _sites(scene, names, index, joints, pairs)

    if scene.world.integrator not in ("semi_implicit_euler", "rk4"):
        raise ModelError(f"unknown integrator '{scene.world.integrator}'",
                         hint="use semi_implicit_euler or rk4")
    if scene.world.contact_model not in CONTACT_MODELS:
        raise ModelError(f"unknown contact model '{scene.world.contact_model}'",
                         hint=f"use {' or '.join(sorted(CONTACT_MODELS))}")
    free_bodies = _free_bodies(joints)
    dt = float(scene.world.timestep)
    if not dt > 0:
        raise ModelError("timestep must be positive")
    nsteps = int(np.ceil(scene.duration / dt - 1e-9))
    return PhysicsModel(
        body_names=tuple(names), joint_names=tuple(j.name for j in scene.joints),
        shape_kinds=shape_kinds, joints=tuple(joints), order=tuple(order), children=children,
        nq=qa, nv=va, sites=tuple(sites), pairs=tuple(pairs), ncon=ncon,
        integrator=scene.world.integrator, contact_model=scene.world.contact_model,
        dt=dt, substeps=max(int(scene.world.substeps), 1), nsteps=max(nsteps, 1),
        free_bodies=free_bodies,
    )


def _contact_pairs(scene: Scene, index: dict, shape_kinds) -> tuple[list[ContactPair], int]:
    """The contact candidate pairs and their number of rows (assigned by the detector's
    fixed count per pair of shape kinds)."""
    pairs: list[ContactPair] = []
    ncon = 0
    eff_index = {}
    for k, use in enumerate(scene.effects):
        if len(use.target) == 2:
            eff_index[(use.effect, frozenset(use.target))] = k
    for a, b in scene.contact_pairs:
        for n in (a, b):
            if n not in index:
                raise ModelError(f"contact pair names unknown body '{n}'")
        ia, ib = index[a], index[b]
        ka, kb = shape_kinds[ia], shape_kinds[ib]
        if ka is None or kb is None:
            raise ModelError(f"contact pair ({a}, {b}) needs shapes on both bodies")
        k = _contact_count(contact_mod, ka, kb)
        pairs.append(ContactPair(ia, ib, ka, kb, tuple(range(ncon, ncon + k)),
                                 eff_index.get(("contact_friction", frozenset((a, b)))),
                                 eff_index.get(("restitution", frozenset((a, b))))))
        ncon += k
    return pairs, ncon


def _sites(scene: Scene, names, index: dict, joints, pairs) -> list[Site]:
    """Where each effect use acts, checked by its registered effect (``EFFECTS``)."""
    sites = []
    jindex = {j.name: i for i, j in enumerate(scene.joints)}
    for k, use in enumerate(scene.effects):
        if use.effect not in EFFECTS:
            raise ModelError(f"effect '{use.effect}' has no physics implementation", span=use.span,
                             hint="known effects: " + ", ".join(sorted(EFFECTS)))
        bodies: tuple[int, ...] = ()
        joint = None
        dofs: tuple[int, ...] = ()
        rows: tuple[int, ...] = ()
        if use.target == ("world",):
            bodies = tuple(range(len(names)))
        else:
            for t in use.target:
                if t in index:
                    bodies += (index[t],)
                elif t in jindex and len(use.target) == 1:
                    joint = jindex[t]
                    tj = joints[index[scene.joints[joint].child]]
                    dofs = tuple(range(tj.vadr, tj.vadr + tj.nv))
                else:
                    raise ModelError(f"effect '{use.effect}' targets unknown '{t}'", span=use.span)
            if len(use.target) == 2:
                for p in pairs:
                    if {p.a, p.b} == set(bodies):
                        rows = p.rows
        EFFECTS[use.effect].check(scene, use, bodies, joint)
        sites.append(Site(use.effect, use.key, k, bodies, joint, dofs, dict(use.tables), rows))
    return sites


def _free_bodies(joints) -> tuple[int, ...] | None:
    """Free bodies sorted by q address if no body moves through a tree joint, else None."""
    by_body = {j.body: j for j in joints}

    def is_static(b):
        while b >= 0:
            if by_body[b].kind != "fixed":
                return False
            b = by_body[b].parent
        return True

    for j in joints:
        if j.kind == "fixed":
            if not is_static(j.body):
                return None
        elif j.kind != "free" or j.parent >= 0:
            return None
    free = sorted((j for j in joints if j.kind == "free"), key=lambda j: j.qadr)
    return tuple(j.body for j in free)


def _contact_count(contact_mod, ka: str, kb: str) -> int:
    """Number K of contact candidates the detector returns for a pair of shape kinds (static)."""
    return int(contact_mod.contact_count(ka, kb))
