"""Small builders of .phys syntax nodes from numbers, for generated scenes (printed by ``fmt``)."""
from __future__ import annotations

import re

import numpy as np

from ..syntax import ast

KEYWORDS = {"import", "scene", "world", "param", "body", "ground", "joint", "contact", "effect",
            "on", "control", "from", "column", "camera", "light", "observe", "where", "at",
            "times", "material", "effect_type", "or", "off", "strength", "vector", "above",
            "below", "true", "false", "pi", "marker", "for", "in"}


def number(x: float, digits: int = 15) -> ast.Expr:
    """A literal for ``x`` rounded to ``digits`` significant digits (negative as ``-x``)."""
    v = float(f"{float(x):.{digits}g}")
    if v == 0:
        return ast.Num("0")
    text = repr(abs(v))
    if text.endswith(".0"):
        text = text[:-2]
    return ast.Neg(ast.Num(text)) if v < 0 else ast.Num(text)


def quantity(x, unit: str | None = None, digits: int = 15) -> ast.Expr:
    """A scalar or vector literal, followed by ``unit`` when given."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 0:
        node = number(arr, digits)
        if unit is None:
            return node
        if isinstance(node, ast.Neg):
            return ast.Neg(ast.WithUnit(node.operand, unit))
        return ast.WithUnit(node, unit)
    node = ast.Vector(tuple(number(v, digits) for v in arr))
    return node if unit is None else ast.WithUnit(node, unit)


def quat(q) -> ast.Expr:
    """``quat(w, x, y, z)`` with the sign chosen so that w >= 0."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q)
    if q[0] < 0:
        q = -q
    return ast.Call("quat", tuple(ast.Arg(None, number(v)) for v in q))


def call(func: str, **kwargs) -> ast.Expr:
    return ast.Call(func, tuple(ast.Arg(k, v) for k, v in kwargs.items()))


def field(key: str, value) -> ast.Field:
    return ast.Field(key, value)


def block(*fields) -> ast.Block:
    return ast.Block(tuple(f for f in fields if f is not None))


class Names:
    """Unique .phys names (one namespace for bodies, joints, controls) from MuJoCo names."""

    def __init__(self):
        self.used: set[str] = {"world"}

    def make(self, raw: str | None, fallback: str) -> str:
        base = re.sub(r"[^A-Za-z0-9_]", "_", raw or "") or fallback
        if base[0].isdigit():
            base = "_" + base
        if base in KEYWORDS:
            base += "_"
        name, k = base, 1
        while name in self.used:
            k += 1
            name = f"{base}_{k}"
        self.used.add(name)
        return name
