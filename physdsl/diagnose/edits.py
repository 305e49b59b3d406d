"""A candidate written into, or taken out of, a scene's text (through ``syntax.edit``, the
printer): its strength an unknown with the library prior; material-level and group candidates
declare one shared ``param``; the unknowns that then hold its strength."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import PhysNameError
from ..syntax import edit, loads
from .candidates import Candidate, material_pairs


def prior_text(prior) -> str:
    """.phys text of a library prior (SI numbers, so no units are needed)."""
    from ..expr import constant_value

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


def with_effect(scene, cand: Candidate, text: str | None = None) -> str:
    """The scene's text (or ``text``) with candidate ``cand`` added, its strength an unknown with
    the library prior. A material-level candidate (target ``(table, *)``) or a shared group
    (``shoulder+elbow``) declares one ``param NAME ~ prior`` and adds the effect on every pair
    of ``table`` that lacks it (every joint of the group), each with that param as its strength;
    a group with a strength per joint (``shoulder&elbow``) adds the effect on each joint.
    A sensor fault becomes its term in the observation's block (``sensor_terms``)."""
    if cand.kind == "sensor":
        from .sensor_terms import with_sensor

        return with_sensor(scene, cand, text)
    decl = scene.effect_library[cand.name]
    filename = str(scene.path or "<string>")
    text = scene.source if text is None else text
    from .physical_scale import prior_text as physical_prior

    prior = physical_prior(scene, cand) or prior_text(decl.strength.prior)
    places = targets(scene, cand)
    strength = prior
    if cand.shared:
        text = edit.add_param(text, cand.shared_param, prior, filename=filename)
        strength = cand.shared_param
    for place in places:
        text = edit.add_effect(text, cand.name, place, {decl.strength.name: strength, **dict(cand.params)},
                               filename=filename)
    return text


def without_effect(scene, cand: Candidate, text: str | None = None) -> str:
    """The scene's text with every effect item of ``cand`` (as ``with_effect`` wrote it) and its
    shared param removed: the step back a drop or a swap takes."""
    filename = str(scene.path or "<string>")
    text = scene.source if text is None else text
    places = ([",".join(p) for p in _pairs_with(scene, cand)] if cand.material
              else [",".join(p.target) for p in cand.parts()])
    for place in places:
        text = edit.remove_item(text, "effect", f"{cand.name}@{place}", filename=filename)
    if cand.shared:
        text = edit.remove_item(text, "param", cand.shared_param, filename=filename)
    return text


def _pairs_with(scene, cand: Candidate) -> list[tuple[str, ...]]:
    """The pairs whose effect ``cand.name`` has the material candidate's shared param."""
    from ..expr import references

    name = strength_name(scene, cand)
    return [tuple(e.target) for e in scene.effects if e.effect == cand.name
            and cand.shared_param in references(e.params[name])]


def load_text(scene, text):
    """A scene from ``text``, its relative data paths resolved beside ``scene``'s file."""
    base = Path(scene.path).parent if scene.path else Path.cwd()
    return loads(text, filename=str(scene.path or "<string>"), base_dir=base)


def unknown_keys(scene, cand: Candidate) -> list[str]:
    """The unknowns that hold the candidate's strength once it is added (``with_effect``)."""
    if cand.kind == "sensor":
        return [f"{cand.target[0]}.{cand.name}"]
    if cand.shared:
        return [cand.shared_param]
    return [f"{p.key}.{strength_name(scene, cand)}" for p in cand.parts()]


def unknown_key(scene, cand: Candidate) -> str:
    """The (first) unknown that holds the candidate's strength once it is added."""
    return unknown_keys(scene, cand)[0]
