"""Pure edits of a .phys scene: on its AST (``effect_added``, ``param_added``, ``value_set``,
``item_removed``: Module -> Module, what the diagnosis and refine loop use, parsing nothing but
the value text) and on its text (``add_effect``, ``add_param``, ``replace_value``,
``remove_item``: parse, edit the AST, print with comments kept). Values are given as .phys value
text (``"0.3 kg"``, ``"~ half_normal(1 cm)"``).
"""
from __future__ import annotations

import dataclasses

from ..errors import PhysNameError
from . import ast
from .ast import strip_spans
from .contact_sugar import SUGAR_FIELD, SUGAR_PARAM
from .parser import parse, parse_field
from .printer import format_module


def _field(key: str, value_text: str) -> ast.Field:
    text = value_text.strip()
    src = f"{key} {text}" if text.startswith("~") else f"{key}: {text}"
    return strip_spans(parse_field(src))


def with_scene_items(module: ast.Module, items) -> ast.Module:
    """``module`` with its scene's items replaced by ``items``."""
    scene = module.scene
    if scene is None:
        raise PhysNameError("the text holds no scene")
    new_scene = dataclasses.replace(scene, items=tuple(items))
    return dataclasses.replace(module, items=tuple(new_scene if i is scene else i
                                                   for i in module.items))


def _target(target) -> tuple[str, ...]:
    if isinstance(target, str):
        return tuple(t.strip() for t in target.strip("()").split(","))
    return tuple(target)


def effect_added(module: ast.Module, effect: str, target, params: dict[str, str] | None = None
                 ) -> ast.Module:
    """Append ``effect EFFECT on TARGET { params }`` inside the scene block."""
    if module.scene is None:
        raise PhysNameError("the text holds no scene")
    fields = tuple(_field(k, v) for k, v in (params or {}).items())
    item = ast.EffectItem(effect, _target(target), ast.Block(fields) if fields else None)
    return with_scene_items(module, module.scene.items + (item,))


def param_added(module: ast.Module, name: str, value_text: str) -> ast.Module:
    """Declare ``param NAME VALUE`` in the scene block, after its last param (first if none)."""
    if module.scene is None:
        raise PhysNameError("the text holds no scene")
    items = list(module.scene.items)
    if any(isinstance(it, ast.Param) and it.name == name for it in items):
        raise PhysNameError(f"the scene already has a param '{name}'")
    last = max((i for i, it in enumerate(items) if isinstance(it, ast.Param)), default=-1)
    items.insert(last + 1, _param(name, value_text))
    return with_scene_items(module, items)


def _set_field(block: ast.Block | None, key_path: list[str], value_text: str) -> ast.Block:
    """``block`` with field ``key_path`` (e.g. ['shape', 'radius']) set to value text, added if missing."""
    return set_field(block, key_path, _field("x", value_text).value)


def set_field(block: ast.Block | None, key_path: list[str], value, create: bool = True):
    """``block`` (possibly None) with field ``key_path`` (e.g. ['shape', 'radius']) set to the
    AST value ``value`` (an expression or a Dist); a missing field is added, or, when not
    ``create``, the result is None."""
    block = block or ast.Block(())
    key = key_path[0]
    fields = list(block.fields)
    if key == "material" and len(key_path) > 1:
        for i, f in enumerate(fields):
            if isinstance(f, ast.MaterialBlock):
                inner = set_field(f.block, key_path[1:], value, create)
                if inner is None:
                    return None
                fields[i] = dataclasses.replace(f, block=inner)
                return dataclasses.replace(block, fields=tuple(fields))
        if not create:
            return None
        fields.append(ast.MaterialBlock(set_field(None, key_path[1:], value)))
        return dataclasses.replace(block, fields=tuple(fields))
    for i, f in enumerate(fields):
        if isinstance(f, ast.Field) and f.key == key:
            if len(key_path) == 1:
                fields[i] = dataclasses.replace(f, value=value)
            else:
                fields[i] = dataclasses.replace(f, value=_set_arg(f.value, key_path[1], value))
            return dataclasses.replace(block, fields=tuple(fields))
    if not create:
        return None
    if len(key_path) > 1:
        raise PhysNameError(f"no field '{key}' to change")
    fields.append(ast.Field(key, value))
    return dataclasses.replace(block, fields=tuple(fields))


def _set_arg(node, name: str, value):
    """A call or record with argument ``name`` set to the AST value ``value`` (``rod.shape.radius``, ``j1.dh.a``)."""
    if isinstance(value, ast.Dist):
        raise PhysNameError(f"'{name}' is an argument; it cannot be '~ dist(...)'",
                            hint="declare 'param NAME ~ dist(...)' and use NAME")
    attr = "args" if isinstance(node, ast.Call) else "fields" if isinstance(node, ast.Record) else None
    if attr is None:
        raise PhysNameError(f"no argument '{name}' here")
    args = list(getattr(node, attr))
    for i, a in enumerate(args):
        if a.name == name:
            args[i] = dataclasses.replace(a, value=value)
            return dataclasses.replace(node, **{attr: tuple(args)})
    args.append(ast.Arg(name, value))
    return dataclasses.replace(node, **{attr: tuple(args)})


def value_set(module: ast.Module, path: str, value_text: str) -> ast.Module:
    """Set the value at ``path``: a param ``L``, a field ``ball.velocity`` / ``rod.shape.radius``,
    an effect parameter ``quadratic_drag@ball.coefficient`` or a noise ``ball.position.noise``.
    A missing field or effect parameter is added."""
    items = list(module.scene.items) if module.scene else []
    if "@" in path:
        return _effect_value_set(module, items, path, value_text)
    parts = path.split(".")
    if len(parts) == 1:
        for i, it in enumerate(items):
            if isinstance(it, ast.Param) and it.name == path:
                items[i] = dataclasses.replace(_param(path, value_text), span=it.span)
                return with_scene_items(module, items)
        raise PhysNameError(f"no param '{path}' in the scene")
    head, rest = parts[0], parts[1:]
    for i, it in enumerate(items):
        if isinstance(it, ast.ObserveItem) and f"{it.target}.{it.quantity}" == ".".join(parts[:2]) \
                and len(rest) == 2:
            items[i] = dataclasses.replace(it, block=_set_field(it.block, rest[1:], value_text))
            return with_scene_items(module, items)
    for i, it in enumerate(items):
        name = getattr(it, "name", None)
        if head == "world" and isinstance(it, ast.WorldItem) or head == "light" and \
                isinstance(it, ast.LightItem) or (name == head and hasattr(it, "block")
                                                  and not isinstance(it, ast.Param)):
            items[i] = dataclasses.replace(it, block=_set_field(it.block, rest, value_text))
            return with_scene_items(module, items)
    raise PhysNameError(f"nothing called '{head}' in the scene")


def _effect_value_set(module: ast.Module, items: list, path: str, value_text: str) -> ast.Module:
    """``value_set`` of an effect parameter ``EFFECT@TARGET.PARAM``: in its effect item, a
    contact block's sugar field (``contact_sugar``) or the world's gravity."""
    key, param = path.rsplit(".", 1)
    effect, target = key.split("@", 1)
    tgt = _target(target)
    for i, it in enumerate(items):
        if isinstance(it, ast.EffectItem) and it.effect == effect and \
                (it.target == tgt or (len(tgt) == 2 and set(it.target) == set(tgt))):
            items[i] = dataclasses.replace(it, block=_set_field(it.block, [param], value_text))
            return with_scene_items(module, items)
        if isinstance(it, ast.ContactItem) and effect in SUGAR_FIELD and \
                {it.a, it.b} == set(tgt) and param == SUGAR_PARAM:
            items[i] = dataclasses.replace(
                it, block=_set_field(it.block, [SUGAR_FIELD[effect]], value_text))
            return with_scene_items(module, items)
        if isinstance(it, ast.WorldItem) and effect == "gravity" and param == "acceleration":
            items[i] = dataclasses.replace(it, block=_set_field(it.block, ["gravity"], value_text))
            return with_scene_items(module, items)
    raise PhysNameError(f"no effect '{key}' in the scene")


def _param(name: str, value_text: str) -> ast.Param:
    f = _field(name, value_text)
    return ast.Param(name, f.value)


def _item_name(it) -> tuple[str, str] | None:
    if isinstance(it, ast.Param):
        return "param", it.name
    if isinstance(it, ast.BodyItem):
        return it.kind, it.name
    if isinstance(it, ast.JointItem):
        return "joint", it.name
    if isinstance(it, ast.EffectItem):
        return "effect", f"{it.effect}@{','.join(it.target)}"
    if isinstance(it, ast.ContactItem):
        return "contact", f"{it.a},{it.b}"
    if isinstance(it, ast.ControlItem):
        return "control", it.name
    if isinstance(it, ast.CameraItem):
        return "camera", it.name
    if isinstance(it, ast.ObserveItem):
        return "observe", f"{it.target}.{it.quantity}"
    if isinstance(it, ast.LightItem):
        return "light", "light"
    if isinstance(it, ast.WorldItem):
        return "world", "world"
    return None


def item_removed(module: ast.Module, kind: str, name: str) -> ast.Module:
    """Remove the item ``kind`` ``name`` (e.g. 'effect', 'quadratic_drag@ball'; 'body', 'ball';
    'observe', 'ball.position'; 'contact', 'floor,ball'; 'import', 'effects/drag.phys')."""
    if kind == "import":
        kept = tuple(i for i in module.items if not (isinstance(i, ast.Import) and i.path == name))
        if len(kept) == len(module.items):
            raise PhysNameError(f"no import \"{name}\"")
        return dataclasses.replace(module, items=kept)
    want = (kind, name.replace(" ", ""))
    items = list(module.scene.items) if module.scene else []
    kept = []
    for it in items:
        got = _item_name(it)
        if got == want or (kind in ("effect", "contact") and got and got[0] == kind
                           and _same_pair(got[1], want[1])):
            continue
        kept.append(it)
    if len(kept) == len(items):
        raise PhysNameError(f"no {kind} '{name}' in the scene")
    # comments inside a removed item go with it
    removed = [it for it in items if it not in kept]
    comments = tuple(c for c in module.comments if not any(_inside(c, it) for it in removed))
    module = dataclasses.replace(module, comments=comments)
    return with_scene_items(module, kept)



# -- the same edits on text: parse, edit the AST, print (comments and blank lines kept) ---------
def add_effect(text: str, effect: str, target, params: dict[str, str] | None = None,
               filename: str = "<string>") -> str:
    """``effect_added`` on .phys text."""
    return format_module(effect_added(parse(text, filename), effect, target, params), text)


def add_param(text: str, name: str, value_text: str, filename: str = "<string>") -> str:
    """``param_added`` on .phys text."""
    return format_module(param_added(parse(text, filename), name, value_text), text)


def replace_value(text: str, path: str, value_text: str, filename: str = "<string>") -> str:
    """``value_set`` on .phys text."""
    return format_module(value_set(parse(text, filename), path, value_text), text)


def remove_item(text: str, kind: str, name: str, filename: str = "<string>") -> str:
    """``item_removed`` on .phys text."""
    return format_module(item_removed(parse(text, filename), kind, name), text)


def _same_pair(a: str, b: str) -> bool:
    ea, _, ta = a.partition("@")
    eb, _, tb = b.partition("@")
    if "@" not in a:
        return set(a.split(",")) == set(b.split(","))
    return ea == eb and set(ta.split(",")) == set(tb.split(","))


def _inside(c: ast.Comment, it) -> bool:
    s = getattr(it, "span", None)
    if s is None or c.span is None:
        return False
    return (s.line, s.column) <= (c.span.line, c.span.column) and c.span.line <= s.end_line
