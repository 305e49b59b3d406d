"""The static PhysicsModel of a Scene: kinematic tree, joint types, q/v index ranges, shapes,
effect sites (built by ``model.build_model``).

Nothing here depends on unknown values; numbers live in the params pytree (``params.py``).
Every body is a tree node with one tree joint to its parent (-1 = world): ``free`` (7 q, 6 v),
``ball`` (4, 3), ``hinge``/``slider`` (1, 1) or ``fixed`` (0, 0, rigidly welded to the parent).
"""
from __future__ import annotations

from dataclasses import dataclass, field

DOFS = {"free": (7, 6), "ball": (4, 3), "hinge": (1, 1), "slider": (1, 1), "fixed": (0, 0)}
SHAPES = ("sphere", "box", "cylinder", "capsule", "plane", "mesh")


@dataclass(frozen=True)
class TreeJoint:
    """The joint between body ``body`` and its parent, with its slices into q and v."""

    kind: str
    body: int
    parent: int  # -1: world
    qadr: int
    nq: int
    vadr: int
    nv: int
    scene_joint: int | None  # index into scene.joints, None for implicit free/weld joints
    dh: bool = False


@dataclass(frozen=True)
class Site:
    """Where one effect use acts: body indices, scene joint index, tree dofs, static tables."""

    effect: str
    key: str
    index: int  # position in scene.effects
    bodies: tuple[int, ...] = ()
    joint: int | None = None
    dofs: tuple[int, ...] = ()
    tables: dict = field(default_factory=dict, hash=False, compare=False)
    contacts: tuple[int, ...] = ()  # candidate contact rows of a pair (rolling resistance)


@dataclass(frozen=True)
class ContactPair:
    """A candidate contact pair: bodies a, b, their shape kinds, and its rows in contact arrays."""

    a: int
    b: int
    kind_a: str
    kind_b: str
    rows: tuple[int, ...]
    friction: int | None  # index of the contact_friction effect use, if any
    restitution: int | None


@dataclass(frozen=True, eq=False)
class PhysicsModel:
    """Static structure; hashable by identity so it can be a jit static argument."""

    body_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    shape_kinds: tuple[str | None, ...]
    joints: tuple[TreeJoint, ...]  # one per body, indexed by body
    order: tuple[int, ...]  # topological order (parents first)
    children: tuple[tuple[int, ...], ...]
    nq: int
    nv: int
    sites: tuple[Site, ...]
    pairs: tuple[ContactPair, ...]
    ncon: int
    integrator: str
    contact_model: str
    dt: float
    substeps: int
    nsteps: int  # recorded steps after t = 0
    # free bodies in q order when every moving body is free and unjointed (the Newton-Euler
    # fast path of ``free.py``; every other body is static), else None (tree algorithms)
    free_bodies: tuple[int, ...] | None = None

    @property
    def nbody(self) -> int:
        return len(self.body_names)

    def ancestors_dofs(self, body: int) -> tuple[int, ...]:
        """v indices of all joints on the path from the world to ``body``."""
        out: list[int] = []
        b = body
        while b >= 0:
            j = self.joints[b]
            out.extend(range(j.vadr, j.vadr + j.nv))
            b = j.parent
        return tuple(sorted(out))
