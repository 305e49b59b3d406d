"""AST -> checked ``Scene``: names bound, units to SI, dimensions/shapes/structure checked, data read.

The order of the work: the library (``library``), the declarations of every item (fields
registered on a ``context.Resolver``, resolved on demand), then the items built by kind
(``world``, ``bodies``, ``joints``, ``markers``, ``view``, ``effects``, ``observations``).
Independent mistakes are collected and raised together as PhysErrors.
"""
from __future__ import annotations

from pathlib import Path

from .. import expr as E
from ..errors import PhysError, PhysNameError, PhysStructureError, Span
from ..scene import Scene, Unknown
from . import ast, experiments
from .bodies import build_body, declare_body
from .bounds import Bounds
from .context import Resolver
from .effects import contact_pairs, effect_decl, scene_effects
from .goals import scene_goal
from .joints import build_joint, check_tree, declare_joint
from .library import load_library
from .loops import annotate, expand, place
from .mapping import clash_hint
from .markers import build_marker
from .observations import scene_observations
from .schema import CAMERA_FIELDS, MARKER_FIELDS
from .view import build_camera, build_light
from .words import close
from .world import build_world

__all__ = ["resolve", "Resolver", "close"]


def resolve(module: ast.Module, source: str, base_dir: Path, path: Path | None = None,
            allowed_paths=()) -> Scene:
    """The checked Scene of a parsed module (``base_dir``: where data and imports are found;
    files outside it, the stdlib and ``allowed_paths`` are refused)."""
    try:
        return run(Resolver(module, source, Path(base_dir), path,
                            Bounds.around(base_dir, allowed_paths)))
    except PhysError as ex:  # errors inside loops name their iteration
        raise annotate(ex) from None


def run(res: Resolver) -> Scene:
    """The Scene of ``res``'s module: library loaded, declarations checked, items built."""
    res.lib = load_library(res.m, res.base, res.source, res.errors, res.path, res.bounds)
    scene = res.m.scene
    if scene is None:
        raise res.err(PhysStructureError, "no scene in this file", Span(res.m.filename, 1, 1),
                      "write 'scene NAME { ... }'")
    extra = [i for i in res.m.items if isinstance(i, ast.SceneDecl)][1:]
    for s in extra:
        res.errors.append(res.err(PhysStructureError, f"a file holds one scene; found a "
                                  f"second one, '{s.name}'", s.span))
    for name, (et, text) in res.lib.effect_types.items():
        decl = res.collect(effect_decl, res, et, text)
        if decl is not None:
            res.effect_library[name] = decl
    # library params
    for name, (p, text) in res.lib.params.items():
        res.register(name, p.value, None)
    scene = expand(scene, res.errors)  # loops unrolled, aliases applied (syntax/loops.py)
    many = experiments.find_item(res, scene)  # recordings read, settings named
    recordings = experiments.declare(res, many, scene) if many is not None else []
    declare(res, scene)
    built = build(res, scene)
    experiments.check_unknowns(res, scene, many is not None)
    res.raise_errors()
    return experiments.attach(res, many, scene, recordings, built) if recordings else built


def declare(res: Resolver, scene: ast.SceneDecl):
    """Register names and field sources; check duplicates and unknown field names."""
    seen: dict[str, Span | None] = {}

    def unique(name, span, kind):
        if name in seen or name == "world":
            where = f" (first at {place(seen[name])})" if seen.get(name) else ""
            res.errors.append(res.err(PhysNameError, f"the name '{name}' is used twice{where}"
                                      if name != "world" else "'world' is a reserved name",
                                      span, clash_hint(name, kind)))
            return False
        seen[name] = span
        return True

    for item in scene.items:
        if isinstance(item, ast.Param):
            if unique(item.name, item.span, "param"):
                res.register(item.name, item.value, None)
        elif isinstance(item, ast.BodyItem):
            if unique(item.name, item.span, item.kind):
                res.items_by_name[item.name] = item.kind
                res.bodies.append(item)
                declare_body(res, item)
        elif isinstance(item, ast.JointItem):
            if unique(item.name, item.span, "joint"):
                res.items_by_name[item.name] = "joint"
                res.joints.append(item)
                declare_joint(res, item)
        elif isinstance(item, ast.MarkerItem):
            if unique(item.name, item.span, "marker"):
                res.items_by_name[item.name] = "marker"
                res.markers.append(item)
                res.declare_fields(item.name, item.block, MARKER_FIELDS, "marker")
        elif isinstance(item, ast.CameraItem):
            if unique(item.name, item.span, "camera"):
                res.items_by_name[item.name] = "camera"
                res.cameras.append(item)
                res.declare_fields(item.name, item.block, CAMERA_FIELDS, "camera", {"size"})


def build(res: Resolver, scene: ast.SceneDecl) -> Scene:
    """Every item built in dependency order (bodies before joints, markers and effects)."""
    world, gravity = build_world(res, scene)
    bodies = [b for b in (res.collect(build_body, res, it) for it in res.bodies) if b]
    body_names = {b.name for b in bodies}
    res.body_index = {b.name: b for b in bodies}
    joints = [j for j in (res.collect(build_joint, res, it) for it in res.joints) if j]
    res.collect(check_tree, res, joints)
    res.joint_index = {j.name: j for j in joints}
    markers = [m for m in (res.collect(build_marker, res, it) for it in res.markers) if m]
    res.marker_index = {m.name: m for m in markers}
    cameras = [c for c in (res.collect(build_camera, res, it) for it in res.cameras) if c]
    lights = [i for i in scene.items if isinstance(i, ast.LightItem)]
    light = res.collect(build_light, res, lights[0]) if lights else None
    for extra in lights[1:]:
        res.errors.append(res.err(PhysStructureError, "a scene has one light", extra.span))
    pairs = contact_pairs(res, bodies, joints, scene.items)
    res.pair_order = {frozenset(p): p for p in pairs}
    effects = scene_effects(res, scene.items, gravity, body_names)
    observations = scene_observations(res, scene.items)
    # every param is resolved (even unused), so its errors show
    for p in [p for p in res.sources if "." not in p]:
        res.collect(res.value, p)
    unknowns = used_in(res)
    return Scene(scene.name, world, tuple(bodies), tuple(joints), tuple(effects),
                 tuple(observations), tuple(cameras), tuple(unknowns), tuple(pairs), light,
                 dict(res.effect_library), res.path, res.source, tuple(markers),
                 scene_goal(res, scene.items))


def used_in(res: Resolver) -> list[Unknown]:
    """The unknowns, each with the fields whose values depend on it."""
    unknowns = []
    for name, u in res.unknowns.items():
        used = tuple(p for p in res.resolved_order
                     if name in E.references(res.memo[p].expr) and p != name)
        unknowns.append(Unknown(u.name, u.prior, u.shape, u.unit, u.span, used or (name,),
                                u.discrete, u.per_experiment))
    return unknowns
