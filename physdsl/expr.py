"""Resolved expressions: numbers in SI that may depend on unknowns, evaluated in JAX.

The resolver turns every number of a scene into one of these nodes (units already converted
to SI, references to other fields already substituted), so later stages never see units or
names other than unknowns. ``evaluate`` is pure and differentiable in the unknowns' values.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Union

import jax.numpy as jnp
import numpy as np


@dataclass(frozen=True)
class Const:
    """A known value in SI: a float or a nested tuple of floats."""

    value: float | tuple

    def array(self) -> np.ndarray:
        return np.asarray(self.value, dtype=float)


@dataclass(frozen=True)
class Ref:
    """The value of the unknown called ``name`` (a key of ``Scene.unknowns``)."""

    name: str


@dataclass(frozen=True)
class Unary:
    op: str  # "-"
    operand: "Expr"


@dataclass(frozen=True)
class Binary:
    op: str  # "+", "-", "*", "/", "^"
    left: "Expr"
    right: "Expr"


@dataclass(frozen=True)
class Call:
    """A built-in function of FUNCTIONS applied to arguments."""

    func: str
    args: tuple["Expr", ...]


@dataclass(frozen=True)
class Vec:
    """A vector whose items are expressions, e.g. (0, 0, 1.2 - L)."""

    items: tuple["Expr", ...]


Expr = Union[Const, Ref, Unary, Binary, Call, Vec]


def quat_from_euler(angles):
    """Unit quaternion (w, x, y, z) of extrinsic x-y-z rotations by ``angles`` (rad), i.e. R = Rz Ry Rx."""
    a = jnp.asarray(angles) * 0.5
    cx, cy, cz = jnp.cos(a[0]), jnp.cos(a[1]), jnp.cos(a[2])
    sx, sy, sz = jnp.sin(a[0]), jnp.sin(a[1]), jnp.sin(a[2])
    return jnp.stack([
        cx * cy * cz + sx * sy * sz,
        sx * cy * cz - cx * sy * sz,
        cx * sy * cz + sx * cy * sz,
        cx * cy * sz - sx * sy * cz,
    ])


def quat_from_axis_angle(axis, angle):
    """Unit quaternion (w, x, y, z) of a rotation by ``angle`` (rad) about ``axis``."""
    axis = jnp.asarray(axis)
    axis = axis / jnp.sqrt(jnp.sum(axis**2) + 1e-300)
    half = 0.5 * jnp.asarray(angle)
    return jnp.concatenate([jnp.cos(half)[None], jnp.sin(half) * axis])


def _safe_norm(x):
    x = jnp.asarray(x)
    sq = jnp.sum(x**2)
    return jnp.where(sq > 0, jnp.sqrt(jnp.where(sq > 0, sq, 1.0)), 0.0)


# name -> (function, number of arguments); the only functions a scene may call.
FUNCTIONS = {
    "sqrt": (jnp.sqrt, 1),
    "sin": (jnp.sin, 1),
    "cos": (jnp.cos, 1),
    "tan": (jnp.tan, 1),
    "exp": (jnp.exp, 1),
    "log": (jnp.log, 1),
    "abs": (jnp.abs, 1),
    "atan2": (jnp.arctan2, 2),
    "norm": (_safe_norm, 1),
    "quat_from_euler": (quat_from_euler, 1),
    "quat_from_axis_angle": (quat_from_axis_angle, 2),
}

_BINARY = {
    "+": jnp.add,
    "-": jnp.subtract,
    "*": jnp.multiply,
    "/": jnp.divide,
    "^": jnp.power,
}


def evaluate(expr: Expr, values: Mapping[str, object]):
    """Value of ``expr`` (a jnp array) given the unknowns' values; pure, jittable, differentiable."""
    if isinstance(expr, Const):
        return jnp.asarray(expr.value, dtype=float)
    if isinstance(expr, Ref):
        return jnp.asarray(values[expr.name])
    if isinstance(expr, Unary):
        return -evaluate(expr.operand, values)
    if isinstance(expr, Binary):
        return _BINARY[expr.op](evaluate(expr.left, values), evaluate(expr.right, values))
    if isinstance(expr, Call):
        func, _ = FUNCTIONS[expr.func]
        return func(*(evaluate(a, values) for a in expr.args))
    if isinstance(expr, Vec):
        return jnp.stack([jnp.asarray(evaluate(i, values), dtype=float) for i in expr.items])
    raise TypeError(f"not an expression: {expr!r}")


def references(expr: Expr) -> set[str]:
    """Names of the unknowns ``expr`` depends on."""
    if isinstance(expr, Ref):
        return {expr.name}
    if isinstance(expr, Unary):
        return references(expr.operand)
    if isinstance(expr, Binary):
        return references(expr.left) | references(expr.right)
    if isinstance(expr, (Call, Vec)):
        items = expr.args if isinstance(expr, Call) else expr.items
        return set().union(*(references(i) for i in items)) if items else set()
    return set()


def is_constant(expr: Expr) -> bool:
    """True when ``expr`` depends on no unknown."""
    return not references(expr)


def constant_value(expr: Expr) -> np.ndarray:
    """Numeric value of an expression that depends on no unknown (for static structure)."""
    if not is_constant(expr):
        raise ValueError("expression depends on unknowns")
    return np.asarray(evaluate(expr, {}), dtype=float)
