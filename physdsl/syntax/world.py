"""The ``world`` block: timestep, duration, substeps, integrator, contact model, medium."""
from __future__ import annotations

from ..errors import PhysNameError, PhysStructureError, PhysTypeError
from ..media import MEDIA
from ..scene import World
from . import ast
from ..registry import CONTACT_MODELS
from .schema import INTEGRATORS, WORLD_FIELDS, spec
from .units import TIME
from .words import close


def build_world(res, scene):
    """(World, the gravity field or None) of the scene's one ``world`` block."""
    items = [i for i in scene.items if isinstance(i, ast.WorldItem)]
    for extra in items[1:]:
        res.errors.append(res.err(PhysStructureError, "a scene has one world block", extra.span))
    if not items:
        return World(), None
    fs = res.fields_of(items[0].block, WORLD_FIELDS, "world")
    kw = {}
    for key, sp in (("timestep", spec(TIME, (), True)), ("duration", spec(TIME, (), True))):
        if key in fs:
            res.register(f"world.{key}", fs[key].value, sp)
            r = res.collect(res.value, f"world.{key}")
            if r is not None:
                v = float(r.expr.array())
                if v <= 0:
                    res.errors.append(res.err(PhysTypeError, f"'{key}' must be positive",
                                              fs[key].value.span))
                kw[key] = v
    if "substeps" in fs:
        node = fs["substeps"].value
        if isinstance(node, ast.Num) and float(node.text).is_integer() and float(node.text) >= 1:
            kw["substeps"] = int(float(node.text))
        else:
            res.errors.append(res.err(PhysTypeError, "'substeps' is a whole number >= 1",
                                      getattr(node, "span", fs["substeps"].span)))
    for key, attr, choices in (("integrator", "integrator", INTEGRATORS),
                               ("contact", "contact_model", CONTACT_MODELS.names()),
                               ("medium", "medium", tuple(MEDIA))):
        if key in fs:
            node = fs[key].value
            word = node.name if isinstance(node, ast.Name) else None
            if word not in choices:
                res.errors.append(res.err(PhysNameError, f"unknown {key} "
                                          f"'{word or '?'}'{close(word or '', choices)}",
                                          getattr(node, "span", fs[key].span),
                                          f"choose {' or '.join(choices)}"))
            else:
                kw[attr] = word
    return World(**kw), fs.get("gravity")
