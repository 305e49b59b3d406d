"""Candidate missing effects: every library effect that could act in a scene and is not in it,
on every target it could act on, plus sensor faults per observation (offset, gain, delay).

Pair effects also get material-level candidates: where several contact pairs share one fixed
body (a table, a floor), the effect on all of them with ONE shared coefficient (a cloth has one
friction coefficient, not one per ball), targeted ``(table, *)``.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..scene import EffectDecl, Scene

# Effects never proposed: they are set up by the user, not discovered.
NOT_CANDIDATES = {"gravity", "control_force", "spring", "constant_force"}
SENSOR_KINDS = ("offset", "gain", "delay")
PAIR_EFFECTS_SKIP = {"damper"}  # acts on pairs too, but only where a spring gives anchors
ANY = "*"  # second target of a material-level candidate: every pair of the fixed body


@dataclass(frozen=True)
class Candidate:
    """A physical effect on a target (``kind == "effect"``) or a sensor fault on an observation."""

    kind: str  # "effect" | "sensor"
    name: str  # effect name, or sensor fault kind
    target: tuple[str, ...]  # body / joint / pair, or (observation name,)
    params: tuple[tuple[str, str], ...] = ()  # .phys value text of extra parameters (e.g. damper anchor)

    @property
    def key(self) -> str:
        return f"{self.name}@{','.join(self.target)}"

    @property
    def material(self) -> bool:
        """A pair effect on every pair of one fixed body with one shared coefficient."""
        return len(self.target) == 2 and self.target[1] == ANY

    @property
    def shared_param(self) -> str:
        """Name of the shared coefficient's ``param`` of a material-level candidate."""
        return f"{self.target[0]}_{self.name}"

    def phys_target(self) -> str:
        return f"({', '.join(self.target)})" if len(self.target) == 2 else self.target[0]


def moving_bodies(scene: Scene) -> list[str]:
    return [b.name for b in scene.bodies if not b.fixed and b.shape is not None
            and b.shape.kind != "plane"]


def physics_candidates(scene: Scene) -> list[Candidate]:
    """Effects of the library that apply to the scene's bodies, joints and contact pairs."""
    present = {(e.effect, tuple(e.target)) for e in scene.effects}
    out: list[Candidate] = []
    for decl in sorted(scene.effect_library.values(), key=lambda d: d.name):
        if decl.name in NOT_CANDIDATES or decl.strength is None:
            continue
        for target, extra in _targets(scene, decl):
            if (decl.name, target) not in present:
                out.append(Candidate("effect", decl.name, target, extra))
        if "pair" in decl.acts_on.split("|") and decl.name not in PAIR_EFFECTS_SKIP:
            for fixed in fixed_bodies(scene):
                if len(material_pairs(scene, decl.name, fixed)) >= 2:
                    out.append(Candidate("effect", decl.name, (fixed, ANY)))
    return out


def fixed_bodies(scene: Scene) -> list[str]:
    return [b.name for b in scene.bodies if b.fixed]


def material_pairs(scene: Scene, effect: str, fixed: str) -> list[tuple[str, str]]:
    """The contact pairs of ``fixed`` that lack ``effect``: those a material-level candidate
    acts on."""
    present = {frozenset(e.target) for e in scene.effects if e.effect == effect}
    return [tuple(p) for p in scene.contact_pairs
            if fixed in p and frozenset(p) not in present]


def _targets(scene: Scene, decl: EffectDecl):
    kinds = set(decl.acts_on.split("|"))
    if "body" in kinds and decl.name != "damper":
        for b in moving_bodies(scene):
            yield (b,), ()
    if decl.name == "damper":  # dampers only where a spring gives the anchor points
        for e in scene.effects:
            if e.effect == "spring":
                anchors = tuple((p, _expr_text(e.params[p])) for p in ("anchor", "attachment")
                                if p in e.params)
                yield tuple(e.target), anchors
    if "joint" in kinds:
        for j in scene.joints:
            if j.kind in ("hinge", "slider"):
                yield (j.name,), ()
    if "pair" in kinds and decl.name not in PAIR_EFFECTS_SKIP:
        for pair in scene.contact_pairs:
            yield tuple(pair), ()


def _expr_text(expr) -> str:
    from ..expr import constant_value, is_constant

    if not is_constant(expr):
        raise ValueError("spring anchor depends on unknowns")
    v = constant_value(expr)
    return "(" + ", ".join(f"{x:.10g}" for x in v.ravel()) + ")" if v.ndim else f"{float(v):.10g}"


def sensor_candidates(scene: Scene) -> list[Candidate]:
    """Sensor faults per trajectory observation: a constant offset, a gain, a time delay."""
    out = []
    for o in scene.observations:
        if o.quantity in ("position", "angle", "velocity", "angular_rate"):
            for kind in SENSOR_KINDS:
                out.append(Candidate("sensor", kind, (o.name,)))
    return out
