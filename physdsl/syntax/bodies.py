"""Bodies and the ground: their fields declared (schema tables), shapes, and the built
``scene.Body``."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import DataError, PhysNameError, PhysStructureError, PhysTypeError
from ..scene import Body, Material, Shape
from . import ast
from .schema import BODY_FIELDS, BODY_FLAGS, GROUND_FIELDS, MATERIAL_FIELDS, SHAPE_ARGS
from .words import close


def declare_body(res, item: ast.BodyItem):
    """Register a body's (or the ground's) fields, its shape's sizes and material."""
    if item.kind == "ground":
        fs = res.declare_fields(item.name, item.block, GROUND_FIELDS, "ground",
                                {"material", "collide"})
    else:
        fs = res.declare_fields(item.name, item.block, BODY_FIELDS, "body",
                                {"shape", "material"} | BODY_FLAGS)
        shape = fs.get("shape")
        if shape is not None:
            declare_shape(res, item.name, shape)
    mat = fs.get("material")
    if mat is not None:
        mfs = res.fields_of(mat.block, MATERIAL_FIELDS, "material")
        for k, f in mfs.items():
            res.register(f"{item.name}.material.{k}", f.value, MATERIAL_FIELDS[k])
    res.body_fields[item.name] = fs


def declare_shape(res, body: str, f: ast.Field):
    """Register the sizes of ``shape: KIND(args)`` as fields ``BODY.shape.ARG``."""
    node = f.value
    if isinstance(node, ast.Name) and node.name in SHAPE_ARGS:
        node = ast.Call(node.name, (), node.span)
    if not isinstance(node, ast.Call) or node.func not in SHAPE_ARGS:
        name = node.func if isinstance(node, ast.Call) else None
        hint = "shapes: sphere(radius:), box(size:), cylinder(radius:, length:), " \
               "capsule(radius:, length:), plane(normal:), mesh(\"file.obj\")"
        msg = (f"unknown shape '{name}'{close(name, SHAPE_ARGS)}" if name
               else "'shape' needs a shape such as sphere(radius: 5 cm)")
        res.errors.append(res.err(PhysNameError if name else PhysTypeError, msg,
                                  getattr(node, "span", f.span), hint))
        return
    table = SHAPE_ARGS[node.func]
    order = list(table)
    for i, a in enumerate(node.args):
        if node.func == "mesh":
            continue
        key = a.name if a.name is not None else (order[i] if i < len(order) else None)
        if key is None or key not in table:
            res.errors.append(res.err(PhysNameError, f"{node.func} has no argument "
                                      f"'{a.name or i + 1}'{close(a.name or '', table)}",
                                      a.span, f"{node.func} takes {', '.join(order)}"))
            continue
        res.register(f"{body}.shape.{key}", a.value, table[key])


def build_body(res, item: ast.BodyItem) -> Body | None:
    """The Body of ``item``: fields resolved, mass or density and shape or inertia checked."""
    n = item.name
    fs = res.body_fields.get(n, {})
    mat = Material(res.opt(f"{n}.material.ambient"), res.opt(f"{n}.material.diffuse"))
    color = res.opt(f"{n}.color")
    if item.kind == "ground":
        normal = res.opt(f"{n}.normal") or E.Const((0.0, 0.0, 1.0))
        point = res.opt(f"{n}.point") or E.Const((0.0, 0.0, 0.0))
        return Body(n, Shape("plane", {"normal": normal}), position=point,
                    orientation=E.Const((1.0, 0.0, 0.0, 0.0)), color=color, material=mat,
                    fixed=True, span=item.span)
    shape = None
    if "shape" in fs:
        shape = build_shape(res, n, fs["shape"])
    fixed = res.flag(fs, "fixed", False) or (shape is not None and shape.kind == "plane")
    mass, density = res.opt(f"{n}.mass"), res.opt(f"{n}.density")
    if "mass" in fs and "density" in fs:
        res.errors.append(res.err(PhysStructureError, f"body '{n}' has both mass and density",
                                  fs["density"].span, "give one of them"))
    if not fixed and "mass" not in fs and "density" not in fs:
        res.errors.append(res.err(PhysStructureError, f"body '{n}' needs a mass or a density",
                                  item.span, "e.g. mass: 200 g  or  density: 1000 kg/m^3"))
    if not fixed and shape is None and "mass" in fs and "inertia" not in fs:
        res.errors.append(res.err(PhysStructureError, f"body '{n}' has no shape and no inertia",
                                  item.span, "give it a shape (or an inertia)"))
    return Body(n, shape, mass, density, res.opt(f"{n}.inertia"), res.opt(f"{n}.position"),
                res.opt(f"{n}.orientation"), res.opt(f"{n}.velocity"),
                res.opt(f"{n}.angular_velocity"), color, mat, fixed, item.span)


def build_shape(res, body: str, f: ast.Field) -> Shape | None:
    """The Shape of a body's ``shape:`` field (sizes positive; a mesh file must exist)."""
    node = f.value
    if isinstance(node, ast.Name):
        node = ast.Call(node.name, (), node.span)
    if not isinstance(node, ast.Call) or node.func not in SHAPE_ARGS:
        return None
    if node.func == "mesh":
        if len(node.args) != 1 or not isinstance(node.args[0].value, ast.Str):
            raise res.err(PhysTypeError, "mesh takes one file name: mesh(\"part.obj\")", node.span)
        file = node.args[0].value.value
        p = res.data_file(file, node.args[0].span, "mesh file")
        if not p.is_file():
            raise DataError("mesh file not found", p, span=node.args[0].span,
                            hint="the path is relative to the scene file")
        return Shape("mesh", {}, p)
    size = {}
    for key in SHAPE_ARGS[node.func]:
        e = res.opt(f"{body}.shape.{key}")
        if e is None and f"{body}.shape.{key}" not in res.sources:
            if node.func == "plane" and key == "normal":
                e = E.Const((0.0, 0.0, 1.0))
            else:
                raise res.err(PhysTypeError, f"{node.func} needs '{key}'", node.span,
                              f"e.g. {node.func}({', '.join(k + ': ...' for k in SHAPE_ARGS[node.func])})")
        if e is not None:
            if isinstance(e, E.Const) and key in ("radius", "length", "size") and \
                    np.any(e.array() <= 0) and not (key == "length" and np.all(e.array() == 0)):
                raise res.err(PhysTypeError, f"the {key} of a {node.func} must be positive",
                              node.span)
            size[key] = e
    return Shape(node.func, size)
