"""What renders a scene: cameras and the light."""
from __future__ import annotations

import numpy as np

from .. import expr as E
from ..errors import PhysStructureError, PhysTypeError
from ..scene import Camera, Light
from . import ast
from .schema import LIGHT_FIELDS


def build_camera(res, item: ast.CameraItem) -> Camera | None:
    """The Camera of ``item`` (position and look_at required; size in whole pixels)."""
    n = item.name
    fs = {f.key: f for f in item.block.fields if isinstance(f, ast.Field)}  # declared already
    for key in ("position", "look_at"):
        if f"{n}.{key}" not in res.sources:
            raise res.err(PhysStructureError, f"camera '{n}' needs '{key}'", item.span)
    size = (64, 64)
    if "size" in fs:
        node = fs["size"].value
        ok = isinstance(node, ast.Vector) and len(node.items) == 2 and all(
            isinstance(i, ast.Num) and float(i.text).is_integer() and float(i.text) > 0
            for i in node.items)
        if not ok:
            raise res.err(PhysTypeError, "camera 'size' is (width, height) in whole pixels",
                          getattr(node, "span", fs["size"].span), "e.g. size: (64, 64)")
        size = (int(float(node.items[0].text)), int(float(node.items[1].text)))
    return Camera(n, res.opt(f"{n}.position"), res.opt(f"{n}.look_at"),
                  res.opt(f"{n}.up") or E.Const((0.0, 0.0, 1.0)),
                  res.opt(f"{n}.fov") or E.Const(float(np.deg2rad(45.0))), size,
                  res.opt(f"{n}.background"), item.span)


def build_light(res, item: ast.LightItem) -> Light:
    """The scene's Light (defaults: from above, ambient 0.3, diffuse 0.7)."""
    fs = res.fields_of(item.block, LIGHT_FIELDS, "light")
    for k, f in fs.items():
        res.register(f"light.{k}", f.value, LIGHT_FIELDS[k])
    return Light(res.opt("light.direction") or E.Const((0.0, 0.0, -1.0)),
                 res.opt("light.ambient") or E.Const(0.3),
                 res.opt("light.diffuse") or E.Const(0.7))
