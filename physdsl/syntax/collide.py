"""Which pairs of bodies may touch: the scene's default contact pairs.

As MuJoCo's parent filter: bodies welded together (``fixed`` joints between bodies) form one
rigid group, and neither two bodies of one group nor two groups joined by a joint collide
(they overlap at the joint by construction, and a contact there could only fight the joint).
Unlike MuJoCo, a body hinged to a ``fixed: true`` body does not touch it either (MuJoCo
counts a fixed body as part of the world, which its filter leaves out). Static bodies never
touch each other; ``collide: false`` takes a body out; a ``contact a, b`` statement puts its
pair back in whatever the rest says (MuJoCo's explicit ``<pair>``).
"""
from __future__ import annotations

from ..scene import Body, Joint


def weld_groups(joints: list[Joint]) -> dict[str, str]:
    """Each body welded to a parent body -> the top body of its welded group."""
    parent = {j.child: j.parent for j in joints if j.kind == "fixed" and j.parent != "world"}

    def top(b: str) -> str:
        seen = {b}
        while b in parent and parent[b] not in seen:  # a cycle is reported elsewhere
            b = parent[b]
            seen.add(b)
        return b

    return {b: top(b) for b in parent}


def contact_pairs(bodies: list[Body], joints: list[Joint], off: set[str],
                  explicit: set[frozenset]) -> list[tuple[str, str]]:
    """Candidate pairs (a, b) in body order, the static body of a pair second."""
    group = weld_groups(joints)
    g = lambda n: group.get(n, n)  # noqa: E731
    joined = {frozenset((g(j.parent), g(j.child))) for j in joints if j.parent != "world"}
    shaped = [b for b in bodies if b.shape is not None]
    pairs = []
    for i, a in enumerate(shaped):
        for b in shaped[i + 1:]:
            if a.fixed and b.fixed:
                continue
            if frozenset((a.name, b.name)) not in explicit and (
                    a.name in off or b.name in off or g(a.name) == g(b.name)
                    or frozenset((g(a.name), g(b.name))) in joined):
                continue
            pairs.append((b.name, a.name) if b.fixed and not a.fixed else (a.name, b.name))
    return pairs
