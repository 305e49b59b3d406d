"""A distilled law as .phys text: the ``effect_type distilled_law`` declaration of the terms it
keeps (units, priors, off value 0) plus its use on the target, ready to be added to a scene."""
from __future__ import annotations

from ..syntax.edit import add_effect
from .law_effect import NAME
from .terms import TERMS, coefficient_unit


def _num(x: float) -> str:
    return f"{float(x):.6g}"


def declaration(kind: str, terms, priors: dict | None = None, center=None,
                note: str = "") -> str:
    """``effect_type distilled_law on body|joint { ... }`` for ``terms`` on a ``kind`` target
    (body, hinge, slider); ``priors``: term -> (mean, sd) in SI (default: normal(0, 1))."""
    on = "body" if kind == "body" else "joint"
    words = " + ".join(f"c_{t} {TERMS[t].words}" for t in terms)
    lhs = "F" if kind == "body" else "tau"
    lines = [f"# {note}" if note else "# a law distilled by physdsl.discover: outside the library",
             f"effect_type {NAME} on {on} {{",
             f"  doc: \"Distilled law (outside the library): {lhs} = {words}\""]
    for i, t in enumerate(terms):  # the first term is the law's strength (add-effect's)
        unit = coefficient_unit(TERMS[t], kind)
        mean, sd = (priors or {}).get(t, (0.0, 1.0))
        lines.append(f"  param {t}: {unit} ~ normal({_num(mean)} {unit}, {_num(sd)} {unit}) off 0"
                     + (" strength" if i == 0 else ""))
    if kind == "body" and any(t.startswith("d") for t in terms):
        c = center if center is not None else (0.0, 0.0, 0.0)
        lines.append(f"  param center: vector m = ({', '.join(_num(x) for x in c)}) m")
    lines.append("}")
    return "\n".join(lines) + "\n"


def law_scene_text(scene_text: str, target: str, kind: str, terms, center=None,
                   values: dict | None = None, priors: dict | None = None,
                   note: str = "") -> str:
    """``scene_text`` with the law declared and used on ``target``: its coefficients fixed
    (``values``, SI) or unknowns with ``priors``."""
    fields = {t: f"{_num(v)} {coefficient_unit(TERMS[t], kind)}"
              for t, v in (values or {}).items()}
    used = add_effect(scene_text, NAME, target, fields or None)
    return declaration(kind, list(terms), priors, center, note) + "\n" + used
