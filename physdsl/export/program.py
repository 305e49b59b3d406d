"""Edits of a parsed program (``ast.Module``) that export and sample make: the scene's items,
an unknown's value written in place, standard-normal params added, file names rebased."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Sequence

from ..errors import PhysError
from ..syntax import ast as A
from ..syntax.contact_sugar import CONTACT_SUGAR
from ..syntax.edit import set_field
from ..syntax.parser import parse_field
from .literals import number


def scene_decl(module):
    """The scene declaration of ``module``, or an error saying export needs one."""
    decl = module.scene
    if decl is None:
        raise PhysError(f"{module.filename}: no scene to export",
                        hint="export reads a scene file: `scene NAME { ... }`")
    return decl


def with_items(module, decl, items):
    """``module`` with the items of its scene declaration ``decl`` replaced by ``items``."""
    new_decl = dataclasses.replace(decl, items=tuple(items))
    return dataclasses.replace(module, items=tuple(new_decl if i is decl else i for i in module.items))


def snippet(text: str):
    """The value (expression or Dist) of a one-field snippet ``key: value`` / ``key ~ dist``."""
    return A.strip_spans(parse_field(text).value)


def ensure_duration(items, duration: float):
    """Items with a world block that sets ``duration`` (added when the world has none)."""
    field = parse_field(f"duration: {number(duration, 10)} s")
    for k, item in enumerate(items):
        if isinstance(item, A.WorldItem):
            if item.block.get("duration") is None:
                block = dataclasses.replace(item.block, fields=item.block.fields + (field,))
                items[k] = dataclasses.replace(item, block=block)
            return items
    return [A.WorldItem(A.Block((field,)))] + list(items)


def set_unknown(module, name: str, value):
    """``module`` with the unknown called ``name`` given ``value`` (an ast Dist or expression).

    Names follow docs/language.md: ``param``, ``body.field``, ``joint.field``,
    ``effect@target.param`` (contact sugar included; a parameter that only had its library
    default prior gets a field), ``target.quantity.noise``.
    """
    decl = scene_decl(module)
    items = list(decl.items)
    found = _set_effect_param(items, name, value) if "@" in name else _set_named(items, name, value)
    if found is None:
        raise PhysError(f"cannot find where unknown '{name}' is written in the scene",
                        hint=f"return it to its prior with --free {name}")
    k, item = found
    items[k] = item
    return with_items(module, decl, items)


def _set_effect_param(items, name: str, value):
    """(index, edited item) writing ``effect@target.param``, or None where it is not written."""
    head, _, param = name.rpartition(".")
    eff, _, tgt = head.partition("@")
    target = tuple(tgt.split(","))
    for k, item in enumerate(items):
        if isinstance(item, A.EffectItem) and item.effect == eff and item.target == target:
            return k, dataclasses.replace(item, block=set_field(item.block, [param], value))
    for k, item in enumerate(items):
        if isinstance(item, A.ContactItem) and target in ((item.a, item.b), (item.b, item.a)):
            for key, e in CONTACT_SUGAR.items():
                block = set_field(item.block, [key], value, create=False) if e == eff else None
                if block is not None:
                    return k, dataclasses.replace(item, block=block)
        if isinstance(item, A.ControlItem) and eff == "control_force" and target == (item.target,):
            block = set_field(item.block, [param], value, create=False)
            if block is not None:
                return k, dataclasses.replace(item, block=block)
    return None


def _set_named(items, name: str, value):
    """(index, edited item) writing ``param``, ``body.field``, ``joint.field`` or
    ``target.quantity.noise``, or None where it is not written."""
    parts = name.split(".")
    for k, item in enumerate(items):
        if len(parts) == 1 and isinstance(item, A.Param) and item.name == name:
            return k, dataclasses.replace(item, value=value)
        block = None
        if len(parts) == 2 and isinstance(item, (A.BodyItem, A.JointItem)) and item.name == parts[0]:
            block = set_field(item.block, [parts[1]], value, create=False)
        if len(parts) == 3 and isinstance(item, A.ObserveItem) \
                and (item.target, item.quantity) == tuple(parts[:2]):
            block = set_field(item.block, [parts[2]], value, create=False)
        if block is not None:
            return k, dataclasses.replace(item, block=block)
    return None


def add_params(module, params: Sequence[tuple[str, str]]):
    """``module`` with ``param NAME ~ DIST`` items (text) placed first in the scene, after world."""
    decl = scene_decl(module)
    new = [A.Param(n, parse_field(f"x ~ {d}").value) for n, d in params]
    items = list(decl.items)
    at = next((k + 1 for k, i in enumerate(items) if isinstance(i, A.WorldItem)), 0)
    return with_items(module, decl, items[:at] + new + items[at:])


def rebase_paths(module, src_dir: Path, out_dir: Path):
    """``module`` with every relative file name (imports found beside the scene, data files,
    meshes) rewritten relative to ``out_dir`` so the program still finds them there."""
    src_dir, out_dir = Path(src_dir).resolve(), Path(out_dir).resolve()
    if src_dir == out_dir:
        return module

    def moved(p: str | None, must_exist: bool = False) -> str | None:
        if p is None or os.path.isabs(p) or (must_exist and not (src_dir / p).exists()):
            return p
        return Path(os.path.relpath(src_dir / p, out_dir)).as_posix()

    def fix(node):
        if isinstance(node, tuple):
            return tuple(fix(n) for n in node)
        if isinstance(node, A.Call) and node.func == "mesh":
            return dataclasses.replace(node, args=tuple(
                dataclasses.replace(a, value=A.Str(moved(a.value.value), a.value.span))
                if isinstance(a.value, A.Str) else a for a in node.args))
        if isinstance(node, A.ObserveItem):
            return dataclasses.replace(node, file=moved(node.file), times=moved(node.times))
        if isinstance(node, A.ControlItem):
            return dataclasses.replace(node, file=moved(node.file))
        if isinstance(node, A.Import):
            return dataclasses.replace(node, path=moved(node.path, must_exist=True))
        if dataclasses.is_dataclass(node) and not isinstance(node, type):
            changes = {f.name: fix(getattr(node, f.name)) for f in dataclasses.fields(node)
                       if f.name not in ("span", "unit_span", "comments")}
            return dataclasses.replace(node, **changes)
        return node

    return fix(module)
