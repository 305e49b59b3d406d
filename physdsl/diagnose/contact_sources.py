"""Where a steady push on a touching body comes from: its contacts.

A body law whose strength is a vector the fit points (``constant_force``; ``wind`` beside
quadratic drag) is a push with no source of its own in the scene. On a body that touches
something, the friction-like contact laws are where a steady force against its motion
physically comes from: sliding friction, rolling resistance (the library's pair laws with a
one-sided scalar strength that is off at zero; restitution, off at 1, acts only at impacts).
So the re-examination offers those laws as alternatives to such a push: on each contact pair
of the body that the fitted rollout shows in contact (a pair it never touches cannot make the
force), on each material candidate of a fixed body it touches, and on all its touching pairs
with one shared coefficient (its surface: target ``(body, *)``), judged like any other swap.
"""
from __future__ import annotations

import numpy as np

from ..scene import EffectDecl, Scene
from .candidates import ANY, Candidate, material_pairs

FORCE_ON = 1e-9  # N: a pair whose normal force exceeds this at some step is in contact


def steady_push(decl: EffectDecl) -> bool:
    """A body law whose strength is a vector (no sign: the fit chooses its direction)."""
    s = decl.strength
    return s is not None and "body" in decl.acts_on.split("|") and bool(tuple(s.shape))


def resisting(decl: EffectDecl) -> bool:
    """A contact-pair law with a one-sided scalar strength that is off at zero (it grows a
    resistance from nothing: sliding friction, rolling resistance)."""
    s = decl.strength
    return (s is not None and "pair" in decl.acts_on.split("|") and not tuple(s.shape)
            and s.off is not None and float(s.off) == 0.0 and s.sign > 0)


def touching(model, values) -> set[frozenset]:
    """The contact pairs (as sets of two body names) with a normal force at some step of
    ``model``'s rollout at ``values`` (every recording's, for a pooled Model)."""
    sim = model.simulator
    pairs = sim.model.pairs
    if not pairs:
        return set()
    rollout = model.simulate(values)
    forces = [np.asarray(r.contact_force) for r in model.recording_rollouts(rollout)]
    names = sim.body_names
    return {frozenset((names[p.a], names[p.b])) for p in pairs
            if p.rows and any(np.any(f[..., list(p.rows)] > FORCE_ON) for f in forces)}


def contact_alternatives(scene: Scene, body: str, pool: list[Candidate],
                         touched: set[frozenset] | None = None) -> list[Candidate]:
    """The resisting contact laws (``resisting``) that could stand for a steady push on
    ``body`` in ``scene`` (which lacks the push): of ``pool`` (its ``physics_candidates``)
    those on a pair of ``body`` in ``touched`` (None: every pair counts) and the material
    candidates of a fixed body with such a pair; and, where ``body`` has two or more touched
    pairs lacking one of those laws, that law on all of its pairs with one shared
    coefficient."""
    lib = scene.effect_library

    def on(pair) -> bool:
        return body in pair and (touched is None or frozenset(pair) in touched)

    out = []
    for c in pool:
        if c.kind != "effect" or len(c.target) != 2 or not resisting(lib[c.name]):
            continue
        pairs = material_pairs(scene, c.name, c.target[0]) if c.material else [c.target]
        if any(on(p) for p in pairs):
            out.append(c)
    # laws the library proposes on a pair (not a damper: it needs a spring's anchors)
    for name in sorted({c.name for c in out if not c.material}):
        if sum(on(p) for p in material_pairs(scene, name, body)) >= 2:
            out.append(Candidate("effect", name, (body, ANY)))
    return out
