"""Candidate missing effects: every library effect that could act in a scene and is not in it,
on every target it could act on, plus sensor faults per observation (the registered ones:
offset, gain, delay and plug-ins; on the observation kinds that take them).

Pair effects also get material-level candidates: where several contact pairs share one fixed
body (a table, a floor), the effect on all of them with ONE shared coefficient (a cloth has one
friction coefficient, not one per ball), targeted ``(table, *)``.

Joint effects also get group candidates: the same law on every hinge (or every slider) of one
articulated body (joints chained through moving bodies), once with ONE shared strength
(target ``shoulder+elbow``) and once with a strength per joint (target ``shoulder&elbow``): a
damped chain has damping in every hinge, one hypothesis.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..expr import constant_value, is_constant
from ..observe.kinds import OBSERVATION_KINDS
from ..observe.sensor import SENSOR_FAULTS
from ..scene import EffectDecl, Scene

# Effects never proposed: they are set up by the user, not discovered. (``constant_force`` is
# proposed: a steady push on a body, a wind's pressure on a ball or an unlevel table's slope.)
NOT_CANDIDATES = {"gravity", "control_force", "spring"}
# Effects that only make sense beside another on the same target: wind is the *change* of
# quadratic drag when the air moves (alone it carries an anti-drag +c|v|v).
REQUIRES = {"wind": "quadratic_drag"}
PAIR_EFFECTS_SKIP = {"damper"}  # acts on pairs too, but only where a spring gives anchors
ANY = "*"  # second target of a material-level candidate: every pair of the fixed body
SHARED, EACH = "+", "&"  # joints of a group candidate: one shared strength / one per joint


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
    def joints(self) -> tuple[str, ...]:
        """The joints of a group candidate (``shoulder+elbow`` / ``shoulder&elbow``), else ()."""
        if len(self.target) != 1:
            return ()
        for sep in (SHARED, EACH):
            if sep in self.target[0]:
                return tuple(self.target[0].split(sep))
        return ()

    @property
    def shared(self) -> bool:
        """One strength for several targets: a material-level or a shared-strength group."""
        return self.material or (bool(self.joints) and SHARED in self.target[0])

    @property
    def shared_param(self) -> str:
        """Name of the shared coefficient's ``param`` (material-level or shared group)."""
        head = "_".join(self.joints) if self.joints else self.target[0]
        return f"{head}_{self.name}"

    def parts(self) -> list["Candidate"]:
        """The per-joint candidates a group candidate is made of (itself if not a group)."""
        if not self.joints:
            return [self]
        return [Candidate(self.kind, self.name, (j,), self.params) for j in self.joints]

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
            needs = REQUIRES.get(decl.name)
            if (decl.name, target) not in present and (needs is None or (needs, target) in present):
                out.append(Candidate("effect", decl.name, target, extra))
        if "pair" in decl.acts_on.split("|") and decl.name not in PAIR_EFFECTS_SKIP:
            for fixed in fixed_bodies(scene):
                if len(material_pairs(scene, decl.name, fixed)) >= 2:
                    out.append(Candidate("effect", decl.name, (fixed, ANY)))
        if "joint" in decl.acts_on.split("|"):
            for group in joint_groups(scene):
                if not any((decl.name, (j,)) in present for j in group):
                    out += [Candidate("effect", decl.name, (sep.join(group),)) for sep in (SHARED, EACH)]
    return out


def joint_groups(scene: Scene) -> list[tuple[str, ...]]:
    """Hinges (and, apart, sliders) of each articulated body, two or more: joints joined
    through moving bodies (a fixed body or the world does not join two chains)."""
    fixed = set(fixed_bodies(scene)) | {"world"}
    comp = {b.name: b.name for b in scene.bodies}

    def root(b):
        while comp.setdefault(b, b) != b:
            b = comp[b]
        return b

    for j in scene.joints:
        if j.parent not in fixed and j.child not in fixed:
            comp[root(j.child)] = root(j.parent)
    groups: dict = {}
    for j in scene.joints:
        if j.kind in ("hinge", "slider"):
            groups.setdefault((root(j.child), j.kind), []).append(j.name)
    return [tuple(g) for g in groups.values() if len(g) >= 2]


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
    if not is_constant(expr):
        raise ValueError("spring anchor depends on unknowns")
    v = constant_value(expr)
    return "(" + ", ".join(f"{x:.10g}" for x in v.ravel()) + ")" if v.ndim else f"{float(v):.10g}"


def sensor_candidates(scene: Scene) -> list[Candidate]:
    """Sensor faults (``SENSOR_FAULTS``: an offset, a gain, a time delay, plug-ins) per
    trajectory observation whose kind takes them (``ObservationKind.fault_candidates``)."""
    out = []
    for o in scene.observations:
        kind = OBSERVATION_KINDS.get(o.quantity)
        if kind is None or not kind.fault_candidates:
            continue
        for fault, spec in SENSOR_FAULTS.items():
            if not (kind.affine or spec.rotations):
                continue
            if o.sensor is None or o.sensor.get(fault) is None:  # a term it has is no candidate
                out.append(Candidate("sensor", fault, (o.name,)))
    return out
