"""Loops, name templates and aliases: a scene's items with every ``for`` unrolled.

``for i in 1..3 { body link{i} { .. } }`` gives three bodies, link1..link3: ``{expr}`` in a
name (or, inside a loop, in a string) is a whole-number expression of the loop variables, and
a loop variable written as a value is that number. ``alias link0 = world`` makes ``link0`` stand
for ``world`` (or any other name) wherever a name is referred to. Every span of an unrolled item
is an ``IterSpan`` that names its iteration, so ``annotate`` can say where a later error arose.
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

from ..errors import PhysError, PhysErrors, PhysNameError, PhysTypeError, Span
from . import ast
from .parser import parse_field

_TEMPLATE = re.compile(r"\{([^{}]*)\}")
# item fields that refer to another item by name (aliases apply there)
_REFS = {ast.JointItem: ("parent", "child"), ast.ContactItem: ("a", "b"),
         ast.ControlItem: ("target",), ast.ObserveItem: ("target",), ast.MarkerItem: ("body",)}
# fields holding text read from files or data, templated inside loops only
_TEXT = {ast.Str: ("value",), ast.ObserveItem: ("file", "where", "times"),
         ast.ControlItem: ("file", "columns")}


@dataclass(frozen=True)
class IterSpan(Span):
    """A span inside a loop body, for one iteration (``iteration``: "i = 3")."""

    iteration: str = ""
    loop_line: int = 0


def expand(scene: ast.SceneDecl, errors: list[PhysError]) -> ast.SceneDecl:
    """``scene`` with loops unrolled, templates filled in and aliases applied; mistakes are
    appended to ``errors`` (the items they are in are left out)."""
    flat: list = []
    for item in scene.items:
        _unroll(item, {}, 0, flat, errors)
    aliases: dict[str, str] = {}
    declared = {getattr(i, "name", None) for i in flat if not isinstance(i, ast.AliasItem)}
    items = []
    for item in flat:
        if not isinstance(item, ast.AliasItem):
            items.append(item)
        elif item.name in aliases or item.name in declared or item.name == "world":
            errors.append(PhysNameError(f"the alias '{item.name}' names something already "
                                        "declared", item.span, "an alias needs a name of its own"))
        else:
            aliases[item.name] = item.target
    if aliases:
        items = [_map(i, lambda s, node, field: aliases.get(s, s) if _is_ref(node, field) else s)
                 for i in items]
    return dataclasses.replace(scene, items=tuple(items))


def _is_ref(node, field: str) -> bool:
    if isinstance(node, ast.Name) or (isinstance(node, ast.EffectItem) and field == "target"):
        return True
    if isinstance(node, ast.Dotted):
        return field == "parts[0]"
    return field in _REFS.get(type(node), ())


def _unroll(item, env: dict[str, int], loop_line: int, out: list, errors: list[PhysError]):
    if isinstance(item, ast.ForLoop):
        if item.var in env:
            errors.append(PhysNameError(f"the loop variable '{item.var}' is already used by an "
                                        "outer loop", item.span, "name this loop's variable "
                                        "differently, e.g. 'for j in ...'"))
            return
        if item.stop < item.start:
            errors.append(PhysTypeError(f"the range {item.start}..{item.stop} is empty", item.span,
                                        "a range runs up: 'for i in 1..6' is 1, 2, ..., 6"))
            return
        for value in range(item.start, item.stop + 1):
            for inner in item.items:
                _unroll(inner, {**env, item.var: value}, item.span.line if item.span else 0,
                        out, errors)
        return
    try:
        out.append(_fill(item, env, loop_line))
    except PhysError as ex:
        errors.append(ex)


def _fill(item, env: dict[str, int], loop_line: int):
    """One item with ``env``'s loop variables substituted (and its spans marked)."""
    iteration = ", ".join(f"{k} = {v}" for k, v in env.items())
    holder = [getattr(item, "span", None)]

    def text(s: str, node, field: str) -> str:
        if "{" not in s:
            return s
        if not env and not _is_name(node, field):
            return s
        return _template(s, env, holder[0])

    def node_fn(node):
        if env and isinstance(node, ast.Name) and node.name in env:
            return ast.Num(str(env[node.name]), node.span)
        span = getattr(node, "span", None)
        if span is not None:
            holder[0] = span
        return None

    def mark(s: Span) -> IterSpan:
        return IterSpan(s.file, s.line, s.column, s.end_line, s.end_column, iteration, loop_line)

    try:
        filled = _map(item, text, node_fn)
    except PhysError as ex:
        if env and ex.span is not None:
            ex.span = mark(ex.span)
        raise
    return _respan(filled, mark) if env else filled


def place(span: Span) -> str:
    """Where ``span`` is, in words: "line 3" or "line 3, iteration i = 1"."""
    where = f"line {span.line}"
    return where + f", iteration {span.iteration}" if isinstance(span, IterSpan) else where


def _is_name(node, field: str) -> bool:
    return field not in _TEXT.get(type(node), ())


def _template(text: str, env: dict[str, int], span: Span | None) -> str:
    """``text`` with each ``{expr}`` replaced by the whole number it evaluates to."""
    def one(m: re.Match) -> str:
        inner = m.group(1).strip()
        if ".." in inner:
            raise PhysTypeError(f"a range ('{{{inner}}}') is not a name", span,
                                f"loop over it: 'for i in {inner} {{ ... {{i}} ... }}'")
        try:
            node = parse_field(f"x: {inner}").value
        except PhysError:
            node = None
        value = _number(node, env, text, span) if node is not None else None
        if value is None:
            raise PhysTypeError(f"cannot read '{{{inner}}}' in '{text}'", span,
                                "write a whole-number expression of loop variables, e.g. {i - 1}")
        if value != int(value):
            raise PhysTypeError(f"'{{{inner}}}' in '{text}' is {value:g}, not a whole number",
                                span, "a name's number must be whole, e.g. {2 * i}")
        return str(int(value))
    return _TEMPLATE.sub(one, text)


def _number(node, env: dict[str, int], text: str, span) -> float | None:
    if isinstance(node, ast.Num):
        return node.value
    if isinstance(node, ast.Name):
        if node.name not in env:
            where = (f"loop variables here: {', '.join(env)}" if env else
                     f"a name with {{...}} goes inside a loop: 'for {node.name} in 1..6 {{ ... }}'")
            raise PhysNameError(f"'{node.name}' in '{text}' is not a loop variable", span, where)
        return float(env[node.name])
    if isinstance(node, ast.Neg):
        v = _number(node.operand, env, text, span)
        return None if v is None else -v
    if isinstance(node, ast.BinOp) and node.op in "+-*/":
        a, b = _number(node.left, env, text, span), _number(node.right, env, text, span)
        if a is None or b is None or (node.op == "/" and b == 0):
            return None
        return {"+": a + b, "-": a - b, "*": a * b, "/": a / b if b else 0.0}[node.op]
    return None


def _map(node, text, node_fn=None):
    """A copy of an AST value with ``text(s, owner, field)`` applied to its strings and
    ``node_fn(node)`` (when it returns a node) replacing nodes; depth first."""
    if isinstance(node, tuple):
        return tuple(_map(n, text, node_fn) for n in node)
    if not (dataclasses.is_dataclass(node) and not isinstance(node, type)):
        return node
    if node_fn is not None:
        new = node_fn(node)
        if new is not None:
            return new
    changes = {}
    for f in dataclasses.fields(node):
        if f.name in ("span", "unit_span", "key", "unit", "kind", "text", "func", "quantity"):
            continue
        value = getattr(node, f.name)
        if isinstance(value, str):
            changes[f.name] = text(value, node, f.name)
        elif isinstance(value, tuple) and value and all(isinstance(v, str) for v in value):
            changes[f.name] = tuple(text(v, node, f"{f.name}[{k}]" if f.name == "parts" else f.name)
                                    for k, v in enumerate(value))
        else:
            changes[f.name] = _map(value, text, node_fn)
    return dataclasses.replace(node, **changes)


def _respan(node, fn):
    """A copy of an AST value with every span ``s`` replaced by ``fn(s)``."""
    if isinstance(node, tuple):
        return tuple(_respan(n, fn) for n in node)
    if not (dataclasses.is_dataclass(node) and not isinstance(node, type)):
        return node
    changes = {}
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if f.name in ("span", "unit_span"):
            changes[f.name] = fn(value) if value is not None else None
        else:
            changes[f.name] = _respan(value, fn)
    return dataclasses.replace(node, **changes)


def annotate(ex: PhysError) -> PhysError:
    """``ex`` with each error inside a loop naming its iteration; an error repeated in every
    iteration at the same place is reported once."""
    errors = ex.errors if isinstance(ex, PhysErrors) else [ex]
    out, seen = [], set()
    for e in errors:
        span = e.span
        if isinstance(span, IterSpan):
            key = (type(e), e.message, span.line, span.column)
            if key in seen:
                continue
            seen.add(key)
            e.message += f" (in iteration {span.iteration} of the loop at line {span.loop_line})"
        out.append(e)
    if len(out) == len(errors) and not isinstance(ex, PhysErrors):
        return ex
    return out[0] if len(out) == 1 else PhysErrors(out)


def unroll_module(module: ast.Module) -> ast.Module:
    """``module`` with its scene's loops unrolled and aliases applied, for tools that edit a
    scene's text item by item (the printed result is the scene written out by hand); raises
    the mistakes ``expand`` finds."""
    scene = module.scene
    if scene is None:
        return module
    errors: list[PhysError] = []
    flat = expand(scene, errors)
    if errors:
        raise annotate(errors[0] if len(errors) == 1 else PhysErrors(errors))
    return dataclasses.replace(module, items=tuple(flat if i is scene else i for i in module.items))
