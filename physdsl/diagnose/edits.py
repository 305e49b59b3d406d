"""A candidate written into, or taken out of, a scene as a value.

A ``Draft`` is a Scene with the AST it was resolved from: a candidate's edit changes the AST
(``syntax.edit``: its strength an unknown with the library prior; material-level and group
candidates declare one shared ``param``) and the resolver turns the result into the new Scene.
Nothing is parsed again and nothing printed: text is made (``Draft.text``) only where a file or
a snippet is written. A Scene resolved from an edited AST has no source text of its own
(``Scene.source`` is ""); its spans point into the text it was edited from.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import PhysNameError
from ..expr import constant_value, references
from ..scene import Scene
from ..syntax import ast, edit, loads, parse, resolve
from ..syntax.printer import format_module
from .candidates import Candidate, material_pairs
from .physical_scale import prior_text as physical_prior
from .sensor_terms import sensor_term


@dataclass(frozen=True)
class Draft:
    """A scene, the AST it is resolved from, and the text that AST's spans point into (its
    comments and blank lines are kept when the AST is printed)."""

    scene: Scene
    module: ast.Module
    source: str

    @classmethod
    def read(cls, path) -> "Draft":
        """The draft of a scene file: read, parsed and resolved once."""
        path = Path(path)
        text = path.read_text(encoding="utf-8")
        module = parse(text, str(path))
        return cls(resolve(module, text, path.parent, path), module, text)

    @classmethod
    def of(cls, scene: Scene) -> "Draft":
        """The draft of a scene read from text (its source parsed once)."""
        return cls(scene, parse(scene.source, str(scene.path or "<string>")), scene.source)

    def add(self, cand: Candidate, module: ast.Module | None = None) -> ast.Module:
        """The AST (``module``, else this draft's) with ``cand`` added as this scene would have
        it: its strength an unknown with the library prior (``physical_scale`` gives drag a
        prior of its physical scale). A material-level candidate (target ``(table, *)``) or a
        shared group (``shoulder+elbow``) declares one ``param NAME ~ prior`` and adds the
        effect on every pair of ``table`` that lacks it (every joint of the group), each with
        that param as its strength; a group with a strength per joint (``shoulder&elbow``) adds
        the effect on each joint. A sensor fault becomes its term in the observation's block."""
        module = self.module if module is None else module
        scene = self.scene
        if cand.kind == "sensor":
            path, value = sensor_term(scene, cand)
            return edit.value_set(module, path, value)
        decl = scene.effect_library[cand.name]
        strength = physical_prior(scene, cand) or prior_text(decl.strength.prior)
        places = targets(scene, cand)
        if cand.shared:
            module = edit.param_added(module, cand.shared_param, strength)
            strength = cand.shared_param
        for place in places:
            module = edit.effect_added(module, cand.name, place,
                                       {decl.strength.name: strength, **dict(cand.params)})
        return module

    def remove(self, cand: Candidate) -> ast.Module:
        """The AST with every effect item of ``cand`` (as ``add`` wrote it) and its shared param
        removed: the step back a drop or a swap takes."""
        places = ([",".join(p) for p in _pairs_with(self.scene, cand)] if cand.material
                  else [",".join(p.target) for p in cand.parts()])
        module = self.module
        for place in places:
            module = edit.item_removed(module, "effect", f"{cand.name}@{place}")
        if cand.shared:
            module = edit.item_removed(module, "param", cand.shared_param)
        return module

    def resolved(self, module: ast.Module) -> "Draft":
        """The draft of an edited AST: its Scene resolved beside this scene's file."""
        scene = resolve(module, self.source, scene_dir(self.scene), self.scene.path)
        return Draft(dataclasses.replace(scene, source=""), module, self.source)

    def with_candidate(self, cand: Candidate) -> "Draft":
        return self.resolved(self.add(cand))

    def without_candidate(self, cand: Candidate) -> "Draft":
        return self.resolved(self.remove(cand))

    def text(self) -> str:
        """The scene as .phys text (printed here, once, e.g. to write a round's file)."""
        return format_module(self.module, self.source)


def prior_text(prior) -> str:
    """.phys text of a library prior (SI numbers, so no units are needed)."""
    args = [_num(constant_value(a)) for a in prior.args]
    args += [f"{k}: {_num(constant_value(v))}" for k, v in prior.kwargs]
    return f"~ {prior.dist}({', '.join(args)})"


def _num(v) -> str:
    v = np.asarray(v)
    if v.ndim == 0:
        return f"{float(v):.6g}"
    return "(" + ", ".join(f"{float(x):.6g}" for x in v.ravel()) + ")"


def strength_name(scene, cand: Candidate) -> str:
    return scene.effect_library[cand.name].strength.name


def targets(scene, cand: Candidate) -> list[str]:
    """.phys targets of the effect items ``cand`` stands for: one, a material's pairs, or a
    group's joints."""
    if cand.material:
        pairs = material_pairs(scene, cand.name, cand.target[0])
        if not pairs:
            raise PhysNameError(f"no contact pair of '{cand.target[0]}' lacks {cand.name}")
        return [f"({a}, {b})" for a, b in pairs]
    return [p.phys_target() for p in cand.parts()]


def with_effect(scene, *cands: Candidate) -> str:
    """The scene's text with ``cands`` added (``Draft.add``, each as ``scene`` would have it):
    what ``add-effect`` writes."""
    draft = Draft.of(scene)
    module = draft.module
    for cand in cands:
        module = draft.add(cand, module)
    return format_module(module, draft.source)


def _pairs_with(scene, cand: Candidate) -> list[tuple[str, ...]]:
    """The pairs whose effect ``cand.name`` has the material candidate's shared param."""
    name = strength_name(scene, cand)
    return [tuple(e.target) for e in scene.effects if e.effect == cand.name
            and cand.shared_param in references(e.params[name])]


def scene_dir(scene) -> Path:
    """The folder a scene's relative paths (data, imports) are read from: its file's, else the
    working directory's."""
    return Path(scene.path).parent if scene.path else Path.cwd()


def load_text(scene, text):
    """A scene from ``text``, its relative data paths resolved beside ``scene``'s file."""
    return loads(text, filename=str(scene.path or "<string>"), base_dir=scene_dir(scene))


def unknown_keys(scene, cand: Candidate) -> list[str]:
    """The unknowns that hold the candidate's strength once it is added (``Draft.add``)."""
    if cand.kind == "sensor":
        return [f"{cand.target[0]}.{cand.name}"]
    if cand.shared:
        return [cand.shared_param]
    return [f"{p.key}.{strength_name(scene, cand)}" for p in cand.parts()]


def unknown_key(scene, cand: Candidate) -> str:
    """The (first) unknown that holds the candidate's strength once it is added."""
    return unknown_keys(scene, cand)[0]
